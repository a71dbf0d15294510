"""Benchmark of the campaign planner's scoring (not part of the test run): prints its figures.

    python benchmarks/bench_plan.py [--candidates 1000] [--naive 20] [--mode both|fast|naive]

The plan is ``plans/kiev680.toml`` (Kiev 680 km, seminar noise per image and per pass, time_tag
and thermal required, every other catalogue effect as a look-alike) with the search fixed to
campaigns of exactly 5 passes × 20 images = **100 images each**, ``--candidates`` of them sampled
from the 15 504 possible (16 pass options).

* fast (``--mode fast``): ``boresight.studies.planning.plan`` end to end — pass options, one Fisher
  block per option, every candidate scored by summing its passes' blocks;
* naive (``--mode naive``): the per-candidate baseline — for each of ``--naive`` candidates,
  build its whole campaign (scenario → noise-free observations) and compute its information
  from scratch (``information_block`` of the whole campaign), then score it the same way.

* shipped (``--mode shipped [--exhaustive]``): the shipped plan as it is (74 612 campaigns of 1–6
  passes) through ``plan`` — the pruned search (``search.pruned_scores``: every candidate bounded,
  only those the bounds do not rule out scored in full); with ``--exhaustive`` also every candidate
  scored in full (``PlanResult.score_every_candidate``, the search before) in the same process, its front
  and choice checked equal, and the CPU seconds of both printed. Whole-process figures:
  ``python -m boresight plan kiev680 --no-plot`` (docs/planning.md, "Speed").

``--mode both`` runs both in one process, checks the naive information equals the block sum
(relative 1e-8) on the candidates both scored, and prints the time per candidate and the
ratio. For whole-process timings from outside, time ``--mode fast`` against
``--mode naive --naive N`` and scale the naive figure by candidates / N.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tomllib

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from machine import machine_line  # benchmarks/machine.py

from boresight.studies.planning import plan, plan_from_dict  # noqa: E402
from boresight.studies.planning.fisher import information_block, noise_free_observations  # noqa: E402
from orbits.scenario import scenario_from_dict  # noqa: E402

PLAN = os.path.join(os.path.dirname(__file__), "..", "plans", "kiev680.toml")


def bench_spec(candidates: int):
    with open(PLAN, "rb") as fh:
        doc = tomllib.load(fh)
    doc["search"].update(passes=[5, 5], images_per_pass=[20], landmarks_per_image=[8], max_candidates=candidates)
    return plan_from_dict(doc, source="bench_plan")


def naive(result, ids):
    """Information of each candidate built from scratch (no block reuse), then scored."""
    from boresight.studies.planning import single_thread_blas

    names = list(result.spec.effect_names) + list(result.spec.lookalikes)
    infos = []
    with single_thread_blas():  # the same BLAS setting as the fast path
        for c in ids:
            sc = scenario_from_dict(result.scenario_document(int(c)), source="naive")
            obs, model = noise_free_observations(sc)
            info, _ = information_block(obs, model, names)
            infos.append(info)
            result.score(info)
    return np.stack(infos)


def shipped(exhaustive: bool):
    from boresight.studies.planning.fisher import NOT_SEPARABLE_RATIO
    from boresight.studies.planning.search import choose, pareto_front

    t0 = time.process_time()
    r = plan(PLAN)
    t_plan = time.process_time() - t0
    n = r.candidates.shape[0]
    print(
        f"pruned search: {n} candidates, {r.timings_s['scored_in_full']} scored in full; plan() {t_plan:.2f} cpu s "
        f"(blocks {r.timings_s['blocks_s']:.2f} s, scoring {r.timings_s['score_s']:.2f} s wall); chosen {r.chosen}, front {r.front.size}"
    )
    if not exhaustive:
        return
    t0 = time.process_time()
    s = r.score_every_candidate()
    t_all = time.process_time() - t0
    tr = np.max(s.sigma_theta_arcsec / np.asarray(r.spec.sigma_theta_arcsec), axis=-1)
    worst = s.name_ratio.max(axis=-1)
    front = pareto_front(s.cost, tr, np.minimum(worst, NOT_SEPARABLE_RATIO))
    chosen = choose(s, (tr <= 1) & (worst <= 1), tr, worst)
    same = np.array_equal(front, r.front) and chosen == r.chosen
    print(f"exhaustive scoring of all {n}: {t_all:.2f} cpu s; front and choice {'equal' if same else 'DIFFER'}")
    if not same:
        raise SystemExit("the pruned search differs from scoring every candidate")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--candidates", type=int, default=1000)
    ap.add_argument("--naive", type=int, default=20)
    ap.add_argument("--mode", choices=("both", "fast", "naive", "shipped"), default="both")
    ap.add_argument("--exhaustive", action="store_true", help="shipped: also score every candidate in full")
    a = ap.parse_args(argv)
    print(machine_line())  # where the figures below were taken
    if a.mode == "shipped":
        return shipped(a.exhaustive)
    spec = bench_spec(a.candidates)
    t0 = time.perf_counter()
    result = plan(spec)
    t_fast = time.perf_counter() - t0
    n_img = {sum(p.images for p in result.passes(c)) for c in range(result.candidates.shape[0])}
    if a.mode == "fast":
        print(f"fast: {result.candidates.shape[0]} candidates of {sorted(n_img)} images in {t_fast:.2f} s")
        return
    ids = np.linspace(0, result.candidates.shape[0] - 1, a.naive).astype(int)
    t0 = time.perf_counter()
    infos = naive(result, ids)
    t_naive = time.perf_counter() - t0
    if a.mode == "naive":
        print(f"naive: {len(ids)} candidates in {t_naive:.2f} s")
        return
    fast_infos = np.stack([result.information(int(c)) for c in ids])
    err = np.max(np.abs(infos - fast_infos) / np.abs(fast_infos).max(axis=(1, 2), keepdims=True))
    per_fast = t_fast / result.candidates.shape[0]
    per_naive = t_naive / len(ids)
    print(f"candidates          {result.candidates.shape[0]} of {result.space_size} (images per candidate: {sorted(n_img)})")
    print(
        f"fast (plan)         {t_fast:.2f} s total: blocks {result.timings_s['blocks_s']:.2f} s, scoring {result.timings_s['score_s']:.2f} s; "
        f"{per_fast * 1e3:.2f} ms per candidate"
    )
    print(f"naive (from scratch) {t_naive:.2f} s for {len(ids)} candidates: {per_naive * 1e3:.1f} ms per candidate")
    print(f"ratio naive/fast    {per_naive / per_fast:.0f}× per candidate")
    print(f"max relative difference of the information (naive vs block sum): {err:.1e}")
    if not err < 1e-8:
        raise SystemExit("the block sum differs from the from-scratch information")


if __name__ == "__main__":
    main()
