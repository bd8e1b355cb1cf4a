"""The results table of a sweep, streamed to disk.

Layout of an output folder::

    DIR/sweep.toml           the sweep file as run (a copy)
    DIR/manifest.json        counts, parts, columns; rewritten atomically after every part
    DIR/parts/part-*.parquet rows of finished cases, one file per flush, each written atomically
    DIR/results.parquet      the table: one row per case of the sweep, in case order (at the end)
    DIR/results.csv          the same, on request
    DIR/cases/<hash>.json    a case's full Result, on request

The parts are the truth: a case is done when a part holds its hash. A kill at any moment leaves
whole parts (each written to a temporary file and renamed), so ``--resume`` reads the hashes of
the parts and solves only the rest. On SIGINT, SIGTERM or SIGHUP the rows held in memory are
flushed before the sweep ends (:func:`geoddp.sweep.run.run_sweep`); only a SIGKILL or a crash
loses them, and ``--resume`` solves those cases again.
Memory stays flat: rows are flushed every ``flush_rows`` rows or ``flush_seconds`` seconds, and
the final table is assembled from the parts, which hold only the table's scalars.
"""
from __future__ import annotations

import io
import os
import time
import uuid
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..output_files import strict_json, write_atomic
from ..validate import InputError

PARTS = "parts"
RESULTS = "results.parquet"
MANIFEST = "manifest.json"
# Columns that depend on the machine and the moment, not on the case: left out when two tables
# are compared (a parallel run against a serial one).
TIMING_COLUMNS = ("solve_time_s", "case_time_s", "sim.wall_time_s", "sim.mpc.solve_median_s", "sim.mpc.solve_p95_s",
                  "sim.mpc.solve_max_s", "sim.mpc.real_time_factor")


def _frame(rows: list[dict[str, Any]]):
    import pandas as pd

    return pd.DataFrame.from_records(rows)


def _parquet_bytes(df) -> bytes:
    buf = io.BytesIO()
    df.to_parquet(buf, index=False)
    return buf.getvalue()


class PartWriter:
    """Collects finished rows and writes them as Parquet parts (atomic), with the manifest.

    Args:
        out: the output folder.
        total: number of cases in the sweep (for the manifest).
        flush_rows: write a part when this many rows wait.
        flush_seconds: ... or when the oldest waiting row is this old.
    """

    def __init__(self, out: Path, total: int, flush_rows: int = 200, flush_seconds: float = 5.0) -> None:
        self.out = Path(out)
        self.parts = self.out / PARTS
        self.parts.mkdir(parents=True, exist_ok=True)
        self.total, self.flush_rows, self.flush_seconds = total, flush_rows, flush_seconds
        self.rows: list[dict[str, Any]] = []
        self.since = time.monotonic()
        # unique per run, also for two runs of one process within a second: parts never overwrite
        self.run = f"{time.strftime('%Y%m%dT%H%M%S')}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        self.seq = 0
        self.written = 0
        self.failed = 0
        self.seen: set[str] = set()  # hashes queued by this writer

    def add(self, row: dict[str, Any]) -> None:
        """Queue a finished case's row; flush when due. A row whose hash this writer already
        queued is ignored (an interrupted sweep records the outcomes in hand once more)."""
        if row["hash"] in self.seen:
            return
        self.seen.add(row["hash"])
        if not self.rows:
            self.since = time.monotonic()
        self.rows.append(row)
        self.written += 1
        self.failed += row.get("status") == "error"
        if len(self.rows) >= self.flush_rows or time.monotonic() - self.since >= self.flush_seconds:
            self.flush()

    def flush(self) -> None:
        """Write the waiting rows as one part (atomic) and update the manifest."""
        if not self.rows:
            return
        self.seq += 1
        path = self.parts / f"part-{self.run}-{self.seq:06d}.parquet"
        write_atomic(path, _parquet_bytes(_frame(self.rows)))
        self.rows = []
        write_manifest(self.out, {"total": self.total, "finished": False})


def part_files(out: Path) -> list[Path]:
    """The finished part files of ``out`` (temporary files of an interrupted write excluded)."""
    d = Path(out) / PARTS
    return sorted(p for p in d.glob("part-*.parquet")) if d.is_dir() else []


def read_part(path: Path, columns: list[str] | None = None):
    """One part file (or the results table) as a DataFrame (only ``columns`` if given).

    Raises:
        InputError: naming ``--out`` and the file, if it is not one this module wrote (they are
            written atomically, so only another program leaves a broken one): moved away, its
            cases are solved again on resume (the table is rebuilt from the parts).
    """
    import pandas as pd
    import pyarrow as pa

    try:
        df = pd.read_parquet(path, columns=columns)
        if "hash" not in df.columns:
            raise ValueError("no hash column")
        return df
    except (OSError, ValueError, KeyError, pa.ArrowException) as exc:
        raise InputError("--out", f"{path}: not a sweep's Parquet file ({' '.join(str(exc).split())[:300]}); move it "
                         "out of the folder and resume (its cases are solved again)") from None


def done_hashes(out: Path) -> set[str]:
    """Hashes of the cases whose rows are on disk (read from the parts' hash column only)."""
    done: set[str] = set()
    for p in part_files(out):
        done.update(read_part(p, ["hash"])["hash"])
    return done


def read_parts(out: Path, hashes: Iterable[str] | None = None):
    """All rows of the parts as one DataFrame, one row per hash (the first written), in case
    order; restricted to ``hashes`` if given (the cases of the current sweep file)."""
    import pandas as pd

    frames = [read_part(p) for p in part_files(out)]
    if not frames:
        return pd.DataFrame()
    df = pd.concat(frames, ignore_index=True)
    if hashes is not None:
        df = df[df["hash"].isin(set(hashes))]
    df = df.drop_duplicates("hash", keep="first").sort_values("case", kind="stable").reset_index(drop=True)
    return df


def write_table(out: Path, df, csv: bool = False) -> list[Path]:
    """Write ``df`` as DIR/results.parquet (and .csv), atomically; returns the paths."""
    paths = [write_atomic(Path(out) / RESULTS, _parquet_bytes(df))]
    if csv:
        paths.append(write_atomic(Path(out) / "results.csv", df.to_csv(index=False)))
    return paths


def write_manifest(out: Path, info: dict[str, Any]) -> Path:
    """DIR/manifest.json (atomic): ``info`` plus the part files and the done count."""
    parts = part_files(out)
    body = dict(info)
    body["parts"] = [p.name for p in parts]
    return write_atomic(Path(out) / MANIFEST, strict_json(body))


def read_table(out: str | Path):
    """The results table of a sweep folder: results.parquet if the sweep finished, else the
    rows of its parts so far (none yet: an empty table).

    Raises:
        InputError: naming ``out``: no such folder, or a folder no sweep has written to (an empty
            table there would look like a sweep with no results).
    """
    import pandas as pd

    out = Path(out)
    p = out / RESULTS
    if p.is_file():
        return read_part(p)
    if not out.is_dir():
        raise InputError("out", f"expected a sweep's output folder, got {str(out)!r} (no such folder)")
    if not (out / MANIFEST).is_file() and not (out / PARTS).is_dir():
        raise InputError("out", f"expected a sweep's output folder, got {str(out)!r} (no {RESULTS}, {MANIFEST} or "
                         f"{PARTS}/ in it)")
    return read_parts(out)
