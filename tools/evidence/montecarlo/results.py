"""The campaign's results on disk: one row per (case, variant), Parquet in parts.

Layout of a campaign directory::

    campaign.json        the CampaignConfig and the number of cases asked for
    dispersions.toml     the dispersion file as used
    rows/part-*.parquet  the rows, written as cases finish (each part atomically: written
                         to a temporary name, then renamed), so a killed campaign loses at
                         most the cases finished since the last flush
    summary.json, *.png  written by ``summary`` / ``plots`` at the end

A case is *finished* when its rows are in a part; resuming runs only the others. Reading
tolerates the same (case, variant) in two parts (keeps the last written).

Columns: ``case, variant, campaign_seed, sim_seed, backend, worker, error, diverged,
wall_time_s, cpu_time_s, sim_time_s``, one float column per dispersion variable (``aero.CL``, ...), one
per channel metric (``alpha.overshoot_pct``, ... NaN where undefined), one per surface figure
(``surf.peak_rudder_deg``, ``surf.travel_total_deg``, ``surf.rate_cmd_limited_s``, ...:
tools.sitl.metrics.SURFACE_FIGURE_KEYS, docs/metrics.md; NaN where unknown), and the decimated
traces ``trace.alpha_deg`` etc. (list<float32>, one sample per ``trace_dt_s``).
"""
from __future__ import annotations

import json
import os
import secrets
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from tools.sitl import metrics as mt
from tools.evidence.montecarlo.case import CHANNELS

ROWS_DIR = "rows"
TRACE_COLUMNS = tuple(f"trace.{ch}_deg" for ch in CHANNELS)
METRIC_COLUMNS = tuple(f"{ch}.{k}" for ch in CHANNELS for k in mt.METRIC_KEYS)
SURFACE_COLUMNS = tuple(f"surf.{k}" for k in mt.SURFACE_FIGURE_KEYS)


def schema(dispersion_keys: list[str]) -> pa.Schema:
    """The Parquet schema of a campaign with these dispersion variables."""
    fields = [
        pa.field("case", pa.int64()), pa.field("variant", pa.string()),
        pa.field("campaign_seed", pa.int64()), pa.field("sim_seed", pa.int64()),
        pa.field("backend", pa.string()), pa.field("worker", pa.string()),
        pa.field("error", pa.string()), pa.field("diverged", pa.bool_()),
        pa.field("wall_time_s", pa.float64()), pa.field("cpu_time_s", pa.float64()),
        pa.field("sim_time_s", pa.float64()),
    ]
    fields += [pa.field(k, pa.float64()) for k in dispersion_keys]
    fields += [pa.field(c, pa.float64()) for c in METRIC_COLUMNS]
    fields += [pa.field(c, pa.float64()) for c in SURFACE_COLUMNS]
    fields += [pa.field(c, pa.list_(pa.float32())) for c in TRACE_COLUMNS]
    return pa.schema(fields)


def _column(rows: list[dict], f: pa.Field):
    if pa.types.is_list(f.type):
        vals = [r.get(f.name) for r in rows]
        return pa.array([None if v is None else np.asarray(v, dtype=np.float32) for v in vals],
                        type=f.type)
    if pa.types.is_floating(f.type):
        return pa.array([float(r.get(f.name, np.nan)) for r in rows], type=f.type)
    return pa.array([r.get(f.name) for r in rows], type=f.type)


class RowWriter:
    """Buffers rows and writes them as Parquet parts (atomic rename), as cases finish.

    Parameters
    ----------
    out_dir : campaign directory.
    dispersion_keys : the dispersion columns.
    flush_rows : write a part once this many rows are buffered ...
    flush_s : ... or once the oldest buffered row is this old (wall s).
    """

    def __init__(self, out_dir: os.PathLike, dispersion_keys: list[str], *,
                 flush_rows: int = 200, flush_s: float = 2.0):
        self.dir = Path(out_dir) / ROWS_DIR
        self.dir.mkdir(parents=True, exist_ok=True)
        self.schema = schema(dispersion_keys)
        self.flush_rows = flush_rows
        self.flush_s = flush_s
        self._buf: list[dict] = []
        self._t_first = 0.0
        # unique per writer: two invocations in the same second must not overwrite parts
        self._stamp = time.strftime("%Y%m%dT%H%M%S") + f"-{os.getpid()}-{secrets.token_hex(3)}"
        self._seq = 0
        self.rows_written = 0

    def add(self, rows: list[dict]) -> None:
        if not self._buf:
            self._t_first = time.monotonic()
        self._buf.extend(rows)
        if len(self._buf) >= self.flush_rows or \
                time.monotonic() - self._t_first >= self.flush_s:
            self.flush()

    def flush(self) -> None:
        if not self._buf:
            return
        table = pa.Table.from_arrays([_column(self._buf, f) for f in self.schema],
                                     schema=self.schema)
        name = f"part-{self._stamp}-{self._seq:05d}.parquet"
        tmp = self.dir / f".{name}.tmp"
        pq.write_table(table, tmp)
        os.replace(tmp, self.dir / name)
        self._seq += 1
        self.rows_written += len(self._buf)
        self._buf = []


def part_files(out_dir: os.PathLike) -> list[Path]:
    d = Path(out_dir) / ROWS_DIR
    return sorted(d.glob("part-*.parquet")) if d.is_dir() else []


def read_rows(out_dir: os.PathLike, columns: list[str] | None = None,
              traces: bool = False) -> pa.Table:
    """Every row of a campaign (deduplicated on (case, variant), sorted).

    ``columns``: only these (plus case, variant); ``traces``: include the trace columns
    (skipped by default: they are the bulk of the data).
    """
    files = part_files(out_dir)
    if not files:
        return pa.table({"case": pa.array([], pa.int64()), "variant": pa.array([], pa.string())})
    tables = []
    for f in files:
        sch = pq.read_schema(f)
        cols = [n for n in sch.names if (traces or n not in TRACE_COLUMNS)]
        if columns is not None:
            cols = [n for n in cols if n in set(columns) | {"case", "variant"}]
        tables.append(pq.read_table(f, columns=cols))
    t = pa.concat_tables(tables, promote_options="default")
    case = t.column("case").to_numpy()
    variant = np.asarray(t.column("variant").to_pylist(), dtype=object)
    # keep the last occurrence of each (case, variant)
    seen: dict[tuple, int] = {}
    for i, key in enumerate(zip(case.tolist(), variant.tolist())):
        seen[key] = i
    keep = np.array(sorted(seen.values(), key=lambda i: (case[i], variant[i])), dtype=np.int64)
    return t.take(pa.array(keep))


def finished_cases(out_dir: os.PathLike, variants: tuple[str, ...]) -> set[int]:
    """Cases with a row for every variant."""
    t = read_rows(out_dir, columns=["case", "variant"])
    have: dict[int, set] = {}
    for c, v in zip(t.column("case").to_pylist(), t.column("variant").to_pylist()):
        have.setdefault(c, set()).add(v)
    need = set(variants)
    return {c for c, vs in have.items() if need <= vs}


def write_json(path: os.PathLike, obj) -> None:
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(obj, indent=2, default=_json_default) + "\n")
    os.replace(tmp, path)


def _json_default(x):
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x)}")
