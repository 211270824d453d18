"""Run a campaign: every case an independent task on Dask distributed.

By default a ``LocalCluster`` of worker processes (one single-threaded worker per core, or
``workers``) is started for the campaign and closed at the end; with ``scheduler`` the cases go
to an existing cluster (``tcp://host:port``; its workers must be able to import this project,
e.g. ``pip install -e .`` on each). A caller may also pass its own ``distributed.Client``.

At most a window of tasks is in flight, so a campaign of any size keeps the scheduler small
and an interruption loses only the cases being computed. Rows are written as cases finish
(``results.RowWriter``); a campaign started again on the same directory with the same
configuration runs only the cases not finished yet (it may also ask for more cases).
"""
from __future__ import annotations

import contextlib
import json
import logging
import os
import secrets
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from tools.evidence.montecarlo import results
from tools.evidence.montecarlo.case import CampaignConfig, code_fingerprint, dispersions_of, run_case
from tools.evidence.montecarlo.progress import Progress

MANIFEST = "campaign.json"


class CampaignError(RuntimeError):
    """The campaign cannot run as asked (e.g. the directory holds a different campaign)."""


@dataclass
class CampaignResult:
    """What one invocation did.

    out_dir : campaign directory; runs : cases asked for; skipped : cases already finished
    before this invocation; ran : cases finished by it; failures : rows diverged or errored
    in it; lost : (case, reason) of tasks that did not return (worker died, cancelled), not
    written, so a resume retries them; interrupted : stopped by KeyboardInterrupt;
    wall_s : total wall time; compute_wall_s : from the first submission to the last result;
    cluster_start_s : time to start (or connect to) the cluster; nthreads : worker threads.
    """

    out_dir: Path
    runs: int
    skipped: int = 0
    ran: int = 0
    failures: int = 0
    lost: list = field(default_factory=list)
    interrupted: bool = False
    wall_s: float = 0.0
    compute_wall_s: float = 0.0
    cluster_start_s: float = 0.0
    nthreads: int = 0


def load_manifest(out_dir: os.PathLike) -> tuple[CampaignConfig, int]:
    """(config, runs) of an existing campaign directory."""
    p = Path(out_dir) / MANIFEST
    if not p.is_file():
        raise CampaignError(f"{out_dir} is not a campaign directory (no {MANIFEST})")
    d = json.loads(p.read_text())
    return CampaignConfig.from_json(d["config"]), int(d["runs"])


def prepare_dir(cfg: CampaignConfig, runs: int, out_dir: os.PathLike) -> None:
    """Create the campaign directory, or check that it holds this same campaign."""
    out = Path(out_dir)
    man = out / MANIFEST
    code = code_fingerprint()
    codes = [code]
    if man.is_file():
        old, old_runs = load_manifest(out)
        if old.identity() != cfg.identity():
            diff = [k for k, v in cfg.to_json().items() if old.to_json().get(k) != v
                    and (k != "dispersions_text" or
                         old.dispersions_canonical() != cfg.dispersions_canonical())]
            raise CampaignError(
                f"{out} holds a different campaign (differs in: {', '.join(diff)}); "
                "use another --out, or the same options to resume it")
        runs = max(runs, old_runs)
        codes = json.loads(man.read_text()).get("code_fingerprints", [])
        if code not in codes:
            warnings.warn(f"{out}: the law/plant code changed since this campaign started "
                          f"(fingerprint {codes[-1] if codes else '?'} -> {code}); its rows will "
                          "mix both versions", stacklevel=3)
            codes.append(code)
    out.mkdir(parents=True, exist_ok=True)
    results.write_json(man, {"config": cfg.to_json(), "runs": runs,
                             "identity": cfg.identity(), "code_fingerprints": codes})
    (out / "dispersions.toml").write_text(cfg.dispersions_text)


def check_applicable(cfg: CampaignConfig) -> None:
    """Fail before starting anything if the dispersions cannot be applied to the scenario.

    Applies case 0's values: a variable the plant's scenario has no key for, or an unknown
    scenario, stops the campaign here with one clear message instead of one error row per case.
    """
    if cfg.backend == "standin":
        return
    from plant_sim.scenario import ScenarioError
    from tools.evidence.montecarlo.case import case_values, dispersed_scenario
    from tools.evidence.montecarlo.dispersions import DispersionError
    values, _ = case_values(cfg, 0)
    try:
        dispersed_scenario(cfg, values)
    except (DispersionError, ScenarioError) as exc:
        raise CampaignError(str(exc)) from None


#: default bound of the connection to an existing scheduler (s)
CONNECT_TIMEOUT_S = 10.0


def scheduler_address(text: str) -> tuple[str, str, int]:
    """(address, host, port) of a Dask scheduler given as ``tcp://host:port`` (also
    ``tls://``, or ``host:port`` meaning tcp); CampaignError naming the expected form."""
    form = "expected tcp://host:port"
    scheme, sep, rest = text.strip().partition("://")
    if not sep:
        scheme, rest = "tcp", text.strip()
    host, colon, port_s = rest.rpartition(":")
    host = host.strip("[]")
    if scheme not in ("tcp", "tls") or not colon or not host or "/" in rest:
        raise CampaignError(f"--scheduler {text!r}: malformed address ({form})")
    try:
        port = int(port_s)
    except ValueError:
        port = -1
    if not 1 <= port <= 65535:
        raise CampaignError(f"--scheduler {text!r}: port must be 1..65535 ({form})")
    return f"{scheme}://{rest}", host, port


def _connect(scheduler: str, timeout_s: float):
    """A Client connected to ``scheduler`` within ``timeout_s``, or CampaignError (one line)."""
    import select
    import socket
    from distributed import Client
    address, host, port = scheduler_address(scheduler)
    # a plain TCP connection first: a dead address fails at once, not after the client's
    # retries; on tcp:// a Dask scheduler speaks first (its handshake), and the client would
    # wait for it without a bound, so a silent listener is refused here
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as sock:
            if address.startswith("tcp://") and not select.select([sock], [], [], timeout_s)[0]:
                raise CampaignError(f"{address} accepts connections but is not a Dask "
                                    f"scheduler (no handshake within {timeout_s:g} s)")
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise CampaignError(f"cannot reach the Dask scheduler at {address}: {reason}") from None
    try:
        return Client(address, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError, ValueError) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise CampaignError(f"cannot connect to the Dask scheduler at {address}: {first}") \
            from None


@contextlib.contextmanager
def cluster_client(workers: int | None = None, scheduler: str | None = None,
                   connect_timeout_s: float = CONNECT_TIMEOUT_S):
    """A distributed.Client: to ``scheduler`` if given (connected within
    ``connect_timeout_s``), else to a new LocalCluster."""
    from distributed import Client, LocalCluster
    if scheduler:
        with _connect(scheduler, connect_timeout_s) as client:
            try:  # an existing cluster may still be starting its workers
                client.wait_for_workers(1, timeout=120)
            except TimeoutError:
                raise CampaignError(f"no worker joined the scheduler {scheduler} "
                                    "within 120 s") from None
            yield client
        return
    n = workers or os.cpu_count() or 1
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                      host="127.0.0.1", dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client


def run_campaign(cfg: CampaignConfig, runs: int, out_dir: os.PathLike, *,
                 client=None, workers: int | None = None, scheduler: str | None = None,
                 connect_timeout_s: float = CONNECT_TIMEOUT_S,
                 progress_stream=None, on_case=None, window: int | None = None,
                 flush_rows: int = 200, flush_s: float = 2.0) -> CampaignResult:
    """Run (or resume) ``runs`` cases of ``cfg`` into ``out_dir``.

    Parameters
    ----------
    client : an existing distributed.Client (else one is made from workers / scheduler).
    scheduler : address of an existing scheduler; connected (within ``connect_timeout_s``)
        before the campaign directory is created, so a dead or malformed address raises
        CampaignError and leaves nothing behind.
    progress_stream : where the progress bar goes (default stderr).
    on_case : called with (case index, rows) after each case's rows are buffered.
    window : tasks in flight at most (default 8 per worker thread, at least 32).

    KeyboardInterrupt (Ctrl-C) stops the campaign cleanly: finished rows are flushed,
    pending tasks cancelled, and the result says ``interrupted``.
    """
    t_start = time.monotonic()
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    disp = dispersions_of(cfg)  # validates the text before anything starts
    check_applicable(cfg)
    with contextlib.ExitStack() as stack:
        if client is None and scheduler:
            client = stack.enter_context(cluster_client(scheduler=scheduler,
                                                        connect_timeout_s=connect_timeout_s))
        return _run_in_dir(cfg, runs, out_dir, client, workers, progress_stream, on_case,
                           window, flush_rows, flush_s, t_start)


def _run_in_dir(cfg, runs, out_dir, client, workers, progress_stream, on_case, window,
                flush_rows, flush_s, t_start) -> CampaignResult:
    disp = dispersions_of(cfg)
    prepare_dir(cfg, runs, out_dir)
    res = CampaignResult(out_dir=Path(out_dir), runs=runs)
    done = results.finished_cases(out_dir, cfg.variants)
    todo = [i for i in range(runs) if i not in done]
    res.skipped = runs - len(todo)
    if not todo:
        res.wall_s = time.monotonic() - t_start
        return res
    writer = results.RowWriter(out_dir, list(disp.dists), flush_rows=flush_rows,
                               flush_s=flush_s)
    bar = Progress(runs, already=res.skipped, stream=progress_stream)
    ctx = contextlib.nullcontext(client) if client is not None else cluster_client(workers)
    try:
        with ctx as cl:
            res.cluster_start_s = time.monotonic() - t_start
            res.nthreads = sum(cl.nthreads().values())
            _drive(cl, cfg, todo, writer, bar, res, on_case,
                   window or max(32, 8 * max(res.nthreads, 1)))
    finally:
        writer.flush()
        bar.close()
        res.wall_s = time.monotonic() - t_start
    return res


def _drive(client, cfg, todo, writer, bar, res, on_case, window) -> None:
    from distributed import as_completed
    nonce = secrets.token_hex(4)
    pending = iter(todo)
    inflight = {}
    # results come back with the completion notice (no extra round trip per case), in
    # batches when several finish together
    ac = as_completed(with_results=True, raise_errors=False)

    def submit(n: int) -> None:
        idx = [i for _, i in zip(range(n), pending)]
        if not idx:
            return
        futs = client.map(run_case, [cfg] * len(idx), idx, pure=False,
                          key=[f"mc-case-{i}-{nonce}" for i in idx])
        for f, i in zip(futs, idx):
            inflight[f.key] = i
        ac.update(futs)

    t0 = time.monotonic()
    bar.t0 = t0  # rate and ETA from the first submission, not from the cluster's start
    try:
        submit(window)
        for batch in ac.batches():
            for fut, rows in batch:
                i = inflight.pop(fut.key)
                if fut.status != "finished":  # the task did not return: retried on resume
                    exc = rows[1] if isinstance(rows, tuple) and len(rows) == 3 else rows
                    first = (str(exc).strip().splitlines() or [""])[0]
                    res.lost.append((i, f"{fut.status}: {type(exc).__name__}: {first}"))
                    bar.update(0, failures=1)
                    continue
                writer.add(rows)
                nfail = sum(1 for r in rows if r["diverged"] or r["error"])
                res.ran += 1
                res.failures += nfail
                bar.update(1, failures=nfail)
                if on_case is not None:
                    on_case(i, rows)
            for fut, _ in batch:
                fut.release()
            submit(len(batch))
    except KeyboardInterrupt:
        res.interrupted = True
        for f in list(ac.futures):
            f.cancel()
    finally:
        res.compute_wall_s = time.monotonic() - t0
