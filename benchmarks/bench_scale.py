"""Real campaigns at real sizes (issue 27): memory and CPU of reading and checking observation files
as the number of observations grows, for shared and for single-use targets; not part of the test run.

    python benchmarks/bench_scale.py [--tiles 1 10 100] [--formats ecsv parquet] [--no-check] [--estimate]
                                     [--montecarlo [RUNS]] [--simulate [RUNS]] [--diagnose]
    python benchmarks/bench_scale.py --strip [--strip-images 10000]      # the big shared-target campaign

Campaigns (``tests/builders.py``: ``campaign_as_flown``, ``single_use``, ``tile``), written to a
temporary folder:

* **as flown** — six passes, 120 images, ~255 landmarks each seen ~5 times, ~1 300 observations;
* **single-use** — the same observations, every one its own ground-control point (a target per row);
* **single-use ×10, ×100** — that campaign tiled (new images, passes and targets; same values):
  1 200 images / ~13 000 observations, 12 000 images / ~130 000 observations.

Each measurement runs in a fresh interpreter (``--measure WHAT FILE``), so one's peak cannot hide
another's: **read** (``ObservationSet.read``: parse, the three tables, every check of the reader and
of the model) and **check** (the read, then the convention doctor ``diagnose_conventions``, what
``boresight check`` and every command's read check run). Reported: CPU seconds (``process_time``,
an untraced run), the peak of traced allocations (``tracemalloc``, numpy's included; a second run)
and the process's peak resident set (``ru_maxrss``, the interpreter and its imports included). A refusal
by the memory budget (``MemoryBudgetError``: a consumer still on the transitional images × targets
view) is reported as such, with its estimate. Ratios are from one run: peak per observation across
the tiles (flat when nothing is images × targets) and CPU ×100 / ×10 (linear: 10).

``--montecarlo [RUNS]`` adds ``boresight montecarlo
FILE --runs RUNS`` (default 100; the CLI in-process, ``_montecarlo``: read check, the file's fit, RUNS
resimulations on the file's rows, RUNS GLS refits). ``--simulate [RUNS]`` measures the simulator itself
(``orbits.draw_errors`` + ``orbits.observe``, RUNS runs, default 100) on ``campaign-6pass`` tiled ×1/×10/×100
(``tests/tiled_simulation.py``: ``tile_arrays``, ``simulate_arrays``), with single-use targets (the rows given) and with the pass
landmarks (the rows found by ``visible_rows``), each in a fresh interpreter; no file is written. ``--diagnose`` adds ``boresight.diagnose`` (the whole
catalogue, the file's noise model) and the independent reference diagnosis ``reference_diagnosis.py`` (on
campaigns of ≤ 3 000 targets), and prints diagnose / reference CPU where both ran, e.g.
``python benchmarks/bench_scale.py --tiles 1 10 --formats ecsv --no-check --diagnose``. Figures: ``docs/benchmarks.md``.

``--estimate`` adds **estimate** per file: the read, then ``boresight.estimate`` (GLS under the
file's noise model), its own CPU (``estimate_cpu_s``) beside the whole measurement's; and, for the
as-flown and single-use ECSV files, ``--pairs`` whole processes of ``python -m boresight estimate
FILE``, on the as-flown file interleaved with the plain-numpy yardstick ``benchmarks/reference_diagnosis.py
--file FILE`` (CPU = user + system of the child from ``os.wait4``, peak RSS of the child, imports included).

``--strip``: the big shared-target campaign (``tests/builders.shared_strip``: 10⁶ observations,
~10⁵ ground-control chips each seen 10 times, 10⁴ images in 20 passes; the noise model per image
and catalogue), written as Parquet (ECSV without pyarrow) and estimated in one fresh interpreter
(no tracing: the process's peak RSS is the figure). Figures: ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
sys.path.insert(0, HERE)


def _run(what: str, path: str, out: dict) -> None:
    """The measured computation: read (and check, or estimate) ``path``; sizes and status into ``out``."""
    from boresight import ObservationSet
    from boresight.observations import doctor
    from orbits.limits import MemoryBudgetError

    try:
        obs = ObservationSet.read(path)
        out.update(n_obs=obs.n_observations, n_images=obs.n_images, n_targets=obs.n_targets)
        if what == "check":
            doctor.diagnose_conventions(obs)
        elif what == "estimate":
            from boresight import estimate
            from boresight.core.disturbances import DisturbanceModel

            t0 = time.process_time()
            est = estimate(obs, weighting="gls", model=DisturbanceModel.from_observations(obs))
            out["estimate_cpu_s"] = time.process_time() - t0
            out["theta_arcsec"] = est.theta.to_value("arcsec").ravel().tolist()
            out["sigma_arcsec"] = est.sigma.to_value("arcsec").ravel().tolist()
        elif what.startswith("montecarlo"):
            _montecarlo(path, int(what.split(":")[1]), out)
        elif what in DIAGNOSE_WHATS:
            _diagnose(what, obs, out)
        out["status"] = "ok"
    except MemoryBudgetError as exc:
        out.update(status="refused", estimate_gib=exc.estimate_bytes / 2**30, message=str(exc)[:300])
    except _Skipped as exc:
        out.update(status="skipped", message=str(exc))


def _montecarlo(path: str, runs: int, out: dict) -> None:
    """``boresight montecarlo FILE --runs RUNS --seed 1 --quiet`` in this interpreter (its printed
    table discarded); the Monte Carlo σ per axis into ``out``."""
    import contextlib
    import io

    from boresight.cli.main import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["montecarlo", path, "--runs", str(runs), "--seed", "1", "--quiet"])
    if rc != 0:
        raise RuntimeError(f"montecarlo {path}: exit {rc}\n{buf.getvalue()[-2000:]}")
    out["montecarlo_table"] = [ln for ln in buf.getvalue().splitlines() if ln[:2] in ("x ", "y ", "z ")]


#: ``--diagnose``: ``boresight.diagnose`` and, on campaigns small enough for its dense nuisance matrix
#: (2K × 3T), the independent plain-numpy diagnosis ``benchmarks/reference_diagnosis.py`` (the yardstick)
DIAGNOSE_WHATS = ("diagnose", "reference")
#: the reference's dense nuisance matrix is (2K) × (3T) float64: 8 GB at the ×10 single-use campaign
REFERENCE_MAX_TARGETS = 3000


def _diagnose(what: str, obs, out: dict) -> None:
    """``boresight.diagnose`` of the file (the whole catalogue, the file's noise model; no report
    written), or the reference diagnosis of ``reference_diagnosis.py`` (status ``skipped`` above
    ``REFERENCE_MAX_TARGETS`` targets); what each named and θ into ``out``."""
    from boresight.core.disturbances import DisturbanceModel

    model = DisturbanceModel.from_observations(obs)
    if what == "diagnose":
        from boresight import diagnose

        d = diagnose(obs, model)
        out.update(named=list(d.named), theta_arcsec=[float(v) for v in d.theta_arcsec])
        return
    if obs.n_targets > REFERENCE_MAX_TARGETS:
        raise _Skipped(f"reference: {obs.n_targets} targets > {REFERENCE_MAX_TARGETS} (its dense nuisance matrix)")
    from reference_diagnosis import reference_diagnosis

    theta, names, _ = reference_diagnosis(obs, model)
    out.update(named=list(names), theta_arcsec=(theta / 4.84813681109536e-06).tolist())


class _Skipped(Exception):
    """A measurement that does not apply to this campaign (said, not timed)."""


def _diagnose_whats(a) -> list:
    """``--diagnose``: the measurement names (none without the option)."""
    return list(DIAGNOSE_WHATS) if a.diagnose else []


def _diagnose_ratios(rows, formats) -> None:
    """diagnose / reference CPU and diagnose's traced peak on each campaign where both ran (issue 27:
    ≤ 1.5× and ≤ 200 MB on the campaign as flown)."""
    for fmt in formats:
        sel = {(r["campaign"], r["what"]): r for r in rows if r["fmt"] == fmt and r["status"] == "ok"}
        for (name, what), d in sel.items():
            ref = sel.get((name, "reference"))
            if what == "diagnose" and ref:
                print(
                    f"{fmt} {name}: diagnose / reference CPU = {d['cpu_s'] / ref['cpu_s']:.2f} "
                    f"(diagnose {d['cpu_s']:.2f} s, {d['peak_traced_mb']:.0f} MB traced; reference {ref['cpu_s']:.2f} s, "
                    f"{ref['peak_traced_mb']:.0f} MB); named {d['named']} / {ref['named']}"
                )


def _measure(what: str, path: str, trace: bool) -> dict:
    """One measurement in this interpreter, after one untimed warm-up of the same computation (so
    the lazy imports of astropy, scipy, … are not counted): the numbers as a dict (printed as JSON by
    ``--measure``)."""
    import gc
    import resource
    import tracemalloc

    _run(what, path, {})
    gc.collect()
    out: dict = {"what": what, "file": os.path.basename(path), "file_mb": os.path.getsize(path) / 2**20}
    if trace:
        tracemalloc.start()
    t0 = time.process_time()
    _run(what, path, out)
    out["cpu_s"] = time.process_time() - t0
    if trace:
        out["peak_traced_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    out["rss_peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # the process's, imports included
    return out


def _child(what: str, path: str, trace: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, ".."))
    cmd = [sys.executable, os.path.abspath(__file__), "--measure", what, path] + (["--trace"] if trace else [])
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=3600)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def _whole(cmd) -> tuple[float, float]:
    """(CPU s, peak RSS MiB) of one whole process ``cmd`` (user + system, from ``os.wait4``)."""
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, ".."))
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    code = os.waitstatus_to_exitcode(status)
    if code not in (0, 3):  # 3: estimate's "did not converge / suspect" exit still did the whole fit
        raise RuntimeError(f"{' '.join(cmd)}: exit {code}: {p.stderr.read().decode()[-2000:]}")
    return ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024


def _vs_reference(name: str, path: str, pairs: int, reference: bool) -> None:
    """``pairs`` whole processes of ``boresight estimate FILE``, interleaved with the reference
    diagnosis's on the same file when ``reference`` (the as-flown campaign: the must-show's yardstick)."""
    import statistics

    A = [sys.executable, "-m", "boresight", "estimate", path]
    B = [sys.executable, os.path.join(HERE, "reference_diagnosis.py"), "--file", path]
    _whole(A)  # warm-up (file cache), not counted
    ra, rb = [], []
    for _ in range(pairs):
        ra.append(_whole(A))
        if reference:
            rb.append(_whole(B))
    med = statistics.median
    ca = [r[0] for r in ra]
    line = (
        f"{name:18s} whole processes ({pairs}, median): `boresight estimate` CPU {med(ca):.2f} s [{min(ca):.2f}, {max(ca):.2f}], "
        f"peak RSS {med([r[1] for r in ra]):.0f} MiB"
    )
    if reference:
        cb = [r[0] for r in rb]
        ratio = [a / b for a, b in zip(ca, cb)]
        line += (
            f"; reference_diagnosis.py (interleaved) CPU {med(cb):.2f} s, peak RSS {med([r[1] for r in rb]):.0f} MiB; "
            f"CPU ratio estimate / reference {med(ratio):.3f} [{min(ratio):.3f}, {max(ratio):.3f}]"
        )
    print(line, flush=True)


def strip_case(images: int) -> None:
    """The big shared-target campaign: write it, then one ``estimate`` measurement in a fresh interpreter."""
    sys.path.insert(0, os.path.join(HERE, "..", "tests"))
    from builders import shared_strip

    t0 = time.process_time()
    obs, _ = shared_strip(n_images=images)
    build_s = time.process_time() - t0
    try:
        import pyarrow  # noqa: F401

        fmt = "parquet"
    except ImportError:
        fmt = "ecsv"
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, f"strip.{fmt}")
        obs.write(path)
        print(
            f"strip: {obs.n_images} images, {obs.n_targets} targets, {obs.n_observations} observations "
            f"(built in {build_s:.1f} s CPU), {fmt} file {os.path.getsize(path) / 2**20:.1f} MB",
            flush=True,
        )
        del obs
        m = _child("estimate", path, trace=False)
    print(
        f"strip estimate: status {m['status']}; read + estimate CPU {m['cpu_s']:.1f} s, of which estimate "
        f"{m.get('estimate_cpu_s', float('nan')):.1f} s; process peak RSS {m['rss_peak_mb']:.0f} MB; "
        f"θ {[round(v, 3) for v in m.get('theta_arcsec', [])]} ± {[round(v, 4) for v in m.get('sigma_arcsec', [])]} arcsec",
        flush=True,
    )


def campaigns(tiles):
    """(name, ObservationSet) for the as-flown campaign, its single-use twin and the twin's tilings."""
    sys.path.insert(0, os.path.join(HERE, "..", "tests"))
    from builders import campaign_as_flown, single_use, tile

    flown, _ = campaign_as_flown()
    once = single_use(flown)
    yield "as flown", flown
    for k in tiles:
        yield ("single-use" if k == 1 else f"single-use ×{k}"), (once if k == 1 else tile(once, k))


def _runs_option(ap: argparse.ArgumentParser, flag: str, help_text: str) -> None:
    """An option that switches a measurement on, with an optional run count: ``FLAG`` alone 100 runs, ``FLAG RUNS``
    that many, absent None (off)."""
    ap.add_argument(flag, type=int, nargs="?", const=100, default=None, metavar="RUNS", help=help_text)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiles", type=int, nargs="+", default=[1, 10, 100], help="single-use tilings to measure")
    ap.add_argument("--formats", nargs="+", default=["ecsv", "parquet"], choices=("ecsv", "parquet"))
    ap.add_argument("--no-check", action="store_true", help="measure the read only")
    ap.add_argument("--estimate", action="store_true", help="also boresight.estimate (GLS) per file")
    _runs_option(ap, "--montecarlo", "also montecarlo FILE --runs RUNS per file")
    _runs_option(ap, "--simulate", "only the simulator (RUNS runs) per tiling")
    ap.add_argument("--measure-simulate", nargs=3, metavar=("KIND", "COPIES", "RUNS"), help=argparse.SUPPRESS)
    ap.add_argument("--diagnose", action="store_true", help="also boresight.diagnose (and the reference diagnosis) per file")
    ap.add_argument("--pairs", type=int, default=3, help="--estimate: whole-process pairs against the reference")
    ap.add_argument("--strip", action="store_true", help="only the big shared-target campaign (10⁶ observations)")
    ap.add_argument("--strip-images", type=int, default=10_000, help="--strip: images (100 observations each)")
    ap.add_argument("--measure", nargs=2, metavar=("WHAT", "FILE"), help=argparse.SUPPRESS)
    ap.add_argument("--trace", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.measure:
        print(json.dumps(_measure(a.measure[0], a.measure[1], a.trace)))
        return
    if a.measure_simulate:
        kind, copies, runs = a.measure_simulate
        print(json.dumps(_simulate_once(kind, int(copies), int(runs), a.trace)))
        return
    if a.simulate is not None:
        from machine import machine_line  # benchmarks/machine.py

        print(machine_line())
        _simulate_scaling(a.tiles, a.simulate)
        return
    from machine import machine_line  # benchmarks/machine.py

    print(machine_line())  # where the figures below were taken
    if a.strip:
        strip_case(a.strip_images)
        return
    formats = list(a.formats)
    if "parquet" in formats:
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            from orbits.errors import extra_hint

            print(f"pyarrow not installed: Parquet skipped ({extra_hint('parquet')})")
            formats.remove("parquet")
    whats = (
        ["read"]
        + ([] if a.no_check else ["check"])
        + (["estimate"] if a.estimate else [])
        + _montecarlo_whats(a)
        + _diagnose_whats(a)
    )
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, obs in campaigns(a.tiles):
            for fmt in formats:
                path = os.path.join(tmp, f"{name.replace(' ', '_').replace('×', 'x')}.{fmt}")
                t0 = time.process_time()
                obs.write(path)
                write_s = time.process_time() - t0
                if a.estimate and fmt == "ecsv" and name in ("as flown", "single-use"):
                    _vs_reference(name, path, a.pairs, reference=name == "as flown")
                for what in whats:
                    m = _child(what, path, trace=False)
                    m["peak_traced_mb"] = _child(what, path, trace=True).get("peak_traced_mb", float("nan"))
                    m.update(campaign=name, fmt=fmt, write_s=write_s)
                    rows.append(m)
                    status = {"ok": "", "skipped": f"   SKIPPED ({m.get('message')})"}.get(
                        m["status"], f"   REFUSED (estimate {m.get('estimate_gib', float('nan')):.3g} GiB)"
                    )
                    print(
                        f"{name:18s} {fmt:7s} {what:8s} {m['n_images']:6d} img {m['n_targets']:7d} tgt {m['n_obs']:7d} obs "
                        f"file {m['file_mb']:7.2f} MB  CPU {m['cpu_s']:7.2f} s  peak traced {m['peak_traced_mb']:8.1f} MB "
                        f"({1e3 * m['peak_traced_mb'] / m['n_obs']:6.2f} kB/obs)  process peak RSS {m['rss_peak_mb']:7.1f} MB{status}"
                        + (f"  (estimate alone: CPU {m['estimate_cpu_s']:.2f} s)" if "estimate_cpu_s" in m else ""),
                        flush=True,
                    )
    _ratios(rows, a.tiles, formats, whats)
    _diagnose_ratios(rows, formats)


def _simulate_once(kind: str, copies: int, runs: int, trace: bool) -> dict:
    """One simulator measurement in this interpreter (after an untimed warm-up on the ×1 campaign)."""
    import gc
    import tracemalloc

    sys.path.insert(0, os.path.join(HERE, "..", "tests"))
    from tiled_simulation import simulate_arrays, tile_arrays

    import orbits

    base = orbits.campaign_arrays(orbits.load_scenario(os.path.join(HERE, "..", "scenarios", "campaign-6pass.toml")))
    single = kind == "single-use"
    simulate_arrays(tile_arrays(base, 1, single), runs, rows=single)
    a = tile_arrays(base, copies, single)
    gc.collect()
    if trace:
        tracemalloc.start()
    t0 = time.process_time()
    m = simulate_arrays(a, runs, rows=single)
    out = {"cpu_s": time.process_time() - t0, "n_obs": m.n_observations, "n_images": m.n_images, "n_targets": m.n_targets}
    if trace:
        out["peak_traced_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    return out


def _simulate_scaling(tiles, runs: int) -> None:
    """``--simulate``: the simulator's CPU and traced peak per observation, single-use and pass
    landmarks, each tiling in a fresh interpreter (untraced for CPU, traced for the peak)."""
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, ".."))
    for kind in ("single-use", "pass-landmarks"):
        got = {}
        for k in tiles:
            m = {}
            for trace in (False, True):
                cmd = [sys.executable, os.path.abspath(__file__), "--measure-simulate", kind, str(k), str(runs)]
                r = subprocess.run(cmd + (["--trace"] if trace else []), env=env, capture_output=True, text=True, timeout=3600)
                if r.returncode != 0:
                    raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}\n{r.stderr[-3000:]}")
                m.update(
                    {
                        key: v
                        for key, v in json.loads(r.stdout.strip().splitlines()[-1]).items()
                        if trace or key != "peak_traced_mb"
                    }
                )
            got[k] = m
            per = 1e3 * m["peak_traced_mb"] * 2**20 / 1e6 / (m["n_obs"] * runs)
            print(
                f"simulate {kind:15s} ×{k:<4d} {m['n_images']:6d} img {m['n_targets']:7d} tgt {m['n_obs']:7d} obs {runs} runs: "
                f"CPU {m['cpu_s']:6.2f} s  peak traced {m['peak_traced_mb']:8.1f} MB ({per:6.3f} kB/obs/run)",
                flush=True,
            )
        if 10 in got and 100 in got:
            print(f"simulate {kind}: CPU ×100 / ×10 = {got[100]['cpu_s'] / got[10]['cpu_s']:.1f} (linear: 10)")
        pk = [got[k]["peak_traced_mb"] / got[k]["n_obs"] for k in got]
        print(f"simulate {kind}: peak traced per observation, max / min over the tilings = {max(pk) / min(pk):.2f}")


def _montecarlo_whats(a) -> list:
    """``--montecarlo RUNS``: the measurement name ``montecarlo:RUNS`` (none without the option)."""
    return [] if a.montecarlo is None else [f"montecarlo:{a.montecarlo}"]


def _ratios(rows, tiles, formats, whats):
    """Peak per observation across tiles and CPU ×100 / ×10, from this run's rows."""
    for fmt in formats:
        for what in whats:
            sel = {r["campaign"]: r for r in rows if r["fmt"] == fmt and r["what"] == what and r["status"] == "ok"}
            per = {k: sel[k]["peak_traced_mb"] / sel[k]["n_obs"] for k in sel if k.startswith("single-use")}
            if len(per) >= 2:
                lo, hi = min(per.values()), max(per.values())
                print(f"{fmt} {what}: peak traced per observation, single-use tilings: max / min = {hi / lo:.2f}")
            a, b = sel.get("single-use ×10"), sel.get("single-use ×100")
            if a and b:
                print(f"{fmt} {what}: CPU ×100 / ×10 = {b['cpu_s'] / a['cpu_s']:.1f} (linear: 10)")
                if "estimate_cpu_s" in a and "estimate_cpu_s" in b:  # the fit alone, without the read
                    print(
                        f"{fmt} {what}: the fit alone, CPU ×100 / ×10 = {b['estimate_cpu_s'] / a['estimate_cpu_s']:.1f} (linear: 10)"
                    )
            f, s = sel.get("as flown"), sel.get("single-use")
            if f and s:
                print(
                    f"{fmt} {what}: single-use / as flown (same observations): CPU {s['cpu_s'] / f['cpu_s']:.2f}, "
                    f"peak {s['peak_traced_mb'] / f['peak_traced_mb']:.2f}"
                )


if __name__ == "__main__":
    main()
