// A multibody cost sum's compiled terms in one call (geoddp.multibody_costs.MultibodyCostSum):
// every term on every node, the nodes split into chunks run by the persistent pool's workers.
//
// Why: a solve evaluates its running and terminal sums at every trial of the line search and at
// every linearisation. Term by term, each call would pay a Python dispatch and a fresh
// pinocchio::Data (which costs more than a node's kinematics), on one thread.
// Here a CostWorkspace (owned by the Python sum, Crocoddyl's model/data split) keeps one Data per
// (model, worker), and the terms run in the sum's order on each node, adding into the same
// outputs, so the results are bitwise those of the term-by-term calls (tested).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <vector>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "costs/costs.hpp"
#include "runtime/parallel.hpp"
#include "bindings/pin_model.hpp"

namespace py = pybind11;

namespace geoddp {

using bind::Arr;

namespace {

using costs::check_stack;
using costs::ConstRowRef;
using costs::RowRef;
using costs::VecRef;
typedef Eigen::Map<const RowMat> CMap;

// The Data of one model, one per worker. The workspace holds the Python pin.Model, so its address
// cannot be reused by another model while the entry lives.
struct ModelDatas {
  py::object owner;
  const pinocchio::Model* model = nullptr;
  std::vector<std::unique_ptr<pinocchio::Data>> per_worker;

  // Worker t's Data, made (or remade, if the model gained joints or frames since) on first use.
  pinocchio::Data& get(int t) {
    std::unique_ptr<pinocchio::Data>& d = per_worker[(size_t)t];
    if (!d || !costs::data_fits(*model, *d))
      d.reset(new pinocchio::Data(*model));
    return *d;
  }
};

struct CostWorkspace {
  std::vector<std::unique_ptr<ModelDatas>> models;

  ModelDatas& entry(py::handle pm, int workers) {
    // the Python object first: an entry holds its owner, so the same object is the same model
    // (and skips Boost.Python's registry lookup, a cost per term and call)
    ModelDatas* e = nullptr;
    for (auto& m : models)
      if (m->owner.ptr() == pm.ptr()) e = m.get();
    if (e != nullptr) {
      if ((int)e->per_worker.size() < workers) e->per_worker.resize((size_t)workers);
      return *e;
    }
    const pinocchio::Model& model = model_from_python(pm);
    for (auto& m : models)
      if (m->model == &model) e = m.get();
    if (e == nullptr) {
      models.emplace_back(new ModelDatas());
      e = models.back().get();
      e->owner = py::reinterpret_borrow<py::object>(pm);
      e->model = &model;
    }
    if ((int)e->per_worker.size() < workers) e->per_worker.resize((size_t)workers);
    return *e;
  }
};

// One term, parsed from its Python tuple (see bind_cost_sum's docstring).
struct Term {
  int type = 0;  // 0 frame residual, 1 state regularisation, 2 control regularisation
  ModelDatas* datas = nullptr;
  pinocchio::FrameIndex frame_id = 0;
  costs::FrameResidual kind = costs::FrameResidual::Placement;
  Arr a, b, W;  // frame: refs; state: q_ref, v_ref; control: u_ref
  bool gauss_newton = false;
};

CMap view(const Arr& x) {
  if (x.ndim() != 2) throw py::value_error("cost_sum: expected 2-d reference and weight arrays");
  return CMap(x.data(), x.shape(0), x.shape(1));
}

// Rows b .. b+n of a stack of K = 1 or N per-node references (K = 1: the same row for all).
ConstRowRef rows_for(const CMap& refs, Eigen::Index N, Eigen::Index b, Eigen::Index n) {
  if (refs.rows() == N && N > 1) return ConstRowRef(refs.middleRows(b, n));
  return ConstRowRef(refs);
}

}  // namespace

void bind_cost_sum(py::module_& m) {
  py::class_<CostWorkspace, std::shared_ptr<CostWorkspace>>(
      m, "CostWorkspace",
      "Per-worker pinocchio::Data for cost_sum, kept between calls (one per cost sum).",
      py::module_local())
      .def(py::init<>())
      .def_property_readonly("models", [](const CostWorkspace& w) { return w.models.size(); });

  m.def(
      "cost_sum",
      [](CostWorkspace& ws, py::list spec, const ConstRowRef& Q, const ConstRowRef& V, const ConstRowRef& U,
         bool derivatives, bool gauss_newton, int threads, VecRef l, RowRef lx, RowRef lxx, RowRef lu,
         RowRef luu) {
        const Eigen::Index N = Q.rows();
        const int workers = node_workers((int)N, threads);
        std::vector<Term> terms(spec.size());
        Eigen::Index nx = -1;
        for (size_t i = 0; i < terms.size(); ++i) {
          const py::tuple t = spec[i].cast<py::tuple>();
          Term& x = terms[i];
          x.type = t[0].cast<int>();
          if (x.type == 0) {  // (0, model, frame_id, kind, refs (K, 16 | 9 | 3), W, gauss_newton)
            x.datas = &ws.entry(t[1], workers);
            const long fid = t[2].cast<long>(), kind = t[3].cast<long>();
            if (fid < 0) throw py::value_error("frame_id: expected a frame index");
            if (kind < 0 || kind > 3)
              throw py::value_error("kind: expected 0 (placement), 1 (rotation), 2 (translation) or 3 (chordal rotation)");
            x.frame_id = (pinocchio::FrameIndex)fid;
            x.kind = static_cast<costs::FrameResidual>(kind);
            x.a = t[4].cast<Arr>();
            x.W = t[5].cast<Arr>();
            x.gauss_newton = t[6].cast<bool>();
            check_stack(view(x.a).rows(), N, "refs");
          } else if (x.type == 1) {  // (1, model, q_ref (K, nq), v_ref (K', nv), W, gauss_newton)
            x.datas = &ws.entry(t[1], workers);
            x.a = t[2].cast<Arr>();
            x.b = t[3].cast<Arr>();
            x.W = t[4].cast<Arr>();
            x.gauss_newton = t[5].cast<bool>();
            check_stack(view(x.a).rows(), N, "q_ref");
            check_stack(view(x.b).rows(), N, "v_ref");
            if (V.rows() != N) throw py::value_error("V: expected shape (N, nv)");
          } else if (x.type == 2) {  // (2, u_ref (K, m), W)
            x.a = t[1].cast<Arr>();
            x.W = t[2].cast<Arr>();
            check_stack(view(x.a).rows(), N, "u_ref");
            if (U.rows() != N) throw py::value_error("U: expected shape (N, m)");
          } else {
            throw py::value_error("cost_sum: expected term types 0 (frame), 1 (state) or 2 (control)");
          }
          if (x.datas != nullptr) {
            const Eigen::Index n = 2 * x.datas->model->nv;
            if (nx >= 0 && n != nx) throw py::value_error("cost_sum: terms on models of different nv");
            nx = n;
          }
        }
        // the outputs are checked whole here, so that a chunk's checks cannot pass by accident
        costs::check_outputs(N, nx >= 0 ? nx : 0, derivatives && nx >= 0, l, lx, lxx);
        for (const Term& x : terms)
          if (x.type == 2) costs::check_outputs(N, U.cols(), derivatives, l, lu, luu);
        py::gil_scoped_release release;
        parallel_nodes_indexed((int)N, threads, [&](int b, int e, int t) {
          const Eigen::Index n = e - b;
          if (n == 0) return;
          VecRef lk(l.segment(b, n));
          // without derivatives lx, lxx, lu, luu may be empty and are not touched
          RowRef lxk(derivatives ? RowRef(lx.middleRows(b, n)) : lx);
          RowRef lxxk(derivatives ? RowRef(lxx.middleRows(b, n)) : lxx);
          for (const Term& x : terms) {
            const CMap A = view(x.a), W = view(x.W);
            const bool gn = x.gauss_newton || gauss_newton;
            if (x.type == 0) {
              const pinocchio::Model& model = *x.datas->model;
              costs::frame_term(model, x.datas->get(t), x.frame_id, x.kind, Q.middleRows(b, n), rows_for(A, N, b, n),
                                W, gn, derivatives, lk, lxk, lxxk);
            } else if (x.type == 1) {
              const CMap Bv = view(x.b);
              costs::state_regularisation(*x.datas->model, Q.middleRows(b, n), V.middleRows(b, n),
                                          rows_for(A, N, b, n), rows_for(Bv, N, b, n), W, gn, derivatives, lk, lxk,
                                          lxxk);
            } else {
              RowRef luk(derivatives ? RowRef(lu.middleRows(b, n)) : lu);
              RowRef luuk(derivatives ? RowRef(luu.middleRows(b, n)) : luu);
              costs::control_regularisation(U.middleRows(b, n), rows_for(A, N, b, n), W, derivatives, lk, luk, luuk);
            }
          }
        });
      },
      py::arg("workspace"), py::arg("terms"), py::arg("Q"), py::arg("V"), py::arg("U"), py::arg("derivatives"),
      py::arg("gauss_newton"), py::arg("threads"), py::arg("l"), py::arg("lx"), py::arg("lxx"), py::arg("lu"),
      py::arg("luu"),
      "Add every term of a cost sum, on N nodes, into l (N,) and with derivatives into lx (N, 2 nv),\n"
      "lxx (N, 4 nv^2), lu (N, m), luu (N, m^2), exactly as the cost_* kernels called term by term in\n"
      "the order given. terms: tuples (0, model, frame_id, kind, refs, W, gauss_newton) for a frame\n"
      "residual (kind as cost_frame_term), (1, model, q_ref, v_ref, W, gauss_newton) for a state\n"
      "regularisation, (2, u_ref, W) for a control one; gauss_newton=True applies to every term.\n"
      "Q (N, nq), V (N, nv), U (N, m) (any (0, 0) array without control terms); threads as expansion.");
}

}  // namespace geoddp
