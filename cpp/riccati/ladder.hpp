// The regularisation ladder's search: geoddp.solver.ladder.LadderSearch rung for rung (the same
// probes in the same order, tested against it through _core.testing.ladder_search). lambda climbs
// lam_{j+1} = max(reg_increase lam_j, reg_min) to the lowest rung whose backward pass factorises:
// galloping above the highest rung that failed (rungs 1, 3, 7, ...; two at a time: 1 and 2, 4 and
// 6, 10 and 14, ...) until one factorises, then bisection (halves, or thirds two at a time).
#pragma once

#include <algorithm>

namespace geoddp {
namespace ctr {

struct LadderSearch {
  int lo = 0;  // the highest rung known to fail (rung 0 failed before the search)
  int hi;      // the lowest known to factorise, or the top rung (above reg_max, never tried)
  int step = 1;
  bool found = false;  // whether rung hi factorised
  bool two;            // two rungs a round (side by side)
  LadderSearch(int top, bool two_) : hi(top), two(two_) {}

  // the next round's rungs into out, ascending; their count (0: done)
  int probes(int out[2]) const {
    const int gap = hi - lo;
    if (gap <= 1) return 0;
    if (found) {
      if (!two || gap == 2) {
        out[0] = lo + gap / 2;
        return 1;
      }
      out[0] = lo + gap / 3;
      out[1] = lo + 2 * gap / 3;
      return 2;
    }
    out[0] = std::min(lo + step, hi - 1);
    out[1] = std::min(lo + 2 * step, hi - 1);
    return two && out[1] > out[0] ? 2 : 1;
  }

  // a round's outcomes, in the order of its probes; the position of the (lowest) rung that
  // factorised (higher ones are not looked at), or -1
  int record(const int* rungs, const bool* ok, int count) {
    for (int i = 0; i < count; ++i) {
      if (ok[i]) {
        hi = rungs[i];
        found = true;
        return i;
      }
      lo = rungs[i];
    }
    if (!found) step *= 2;
    return -1;
  }
};

}  // namespace ctr
}  // namespace geoddp
