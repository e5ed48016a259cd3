"""The episodes stage alone on :mod:`benchmarks.episodes_combined`'s recordings, on exactly the
inputs ``cdprid identify`` passes it (its aligned window, its data-chosen cutoff, trim and
winch lengths, caught at :func:`cdprid.identify._episodes.without_episodes`' call of
``find_episodes``): pushes located, false episodes, episodes on the clean twins, scored as
there. Minutes instead of the full benchmark's identify and diagnose; the estimates (mass,
m s_G, findings) need the full benchmark.

Run from the repository root::

    nice -n 10 python -m benchmarks.episodes_combined_stage [--seeds 0-5]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path


class _Caught(Exception):
    pass


def stage_inputs(rec, workdir: Path):
    """``(robot, sig, kwargs)`` of identify's call of ``find_episodes`` on ``rec``."""
    from tests._testbench import write

    import cdprid.identify  # noqa: F401  (the face loads the module whose call is caught)
    from benchmarks.episodes_combined import _identify

    # the episodes step's module as the face loaded it (instrumentation, not an API)
    ie = sys.modules["cdprid.identify._episodes"]

    path = write(rec, workdir, overwrite=True)
    orig, got = ie.find_episodes, {}

    def catch(robot, sig, **kw):
        got["args"] = (robot, sig, kw)
        raise _Caught

    ie.find_episodes = catch
    try:
        _identify(path)
    except _Caught:
        pass
    finally:
        ie.find_episodes = orig
    return got["args"]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="0-5", help="a range 0-5 or a list 0,2,5")
    a = p.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    from tests._testbench import floor8_combined

    from benchmarks.episodes_combined import false_episodes, push_scores
    from cdprid.episodes import find_episodes

    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi) + 1) if hi else [int(s) for s in a.seeds.split(",")]
    n_false = n_clean = n_loc = n_push = 0
    with tempfile.TemporaryDirectory() as d:
        for seed in seeds:
            for twin in ("combined", "clean"):
                rec = floor8_combined(seed, clean=twin == "clean")
                robot, sig, kw = stage_inputs(rec, Path(d) / f"{twin}-{seed}")
                t0 = time.perf_counter()
                eps = find_episodes(robot, sig, **kw).as_json()
                wall = time.perf_counter() - t0
                ps = push_scores(rec.pushes, eps)
                bad = false_episodes(rec, eps) if twin == "combined" else eps
                n_false += len(bad) if twin == "combined" else 0
                n_clean += len(bad) if twin == "clean" else 0
                n_loc += sum(q["located"] for q in ps)
                n_push += len(ps)
                edges = ", ".join(f"{q['start_err']:+.2f}/{q['end_err']:+.2f}" for q in ps
                                  if q["start_err"] is not None)
                print(f"seed {seed} {twin} (cutoff {kw['cutoff_hz']:g} Hz, {wall:.0f} s): "
                      f"pushes {sum(q['located'] for q in ps)}/{len(ps)} [{edges}], "
                      f"{'false' if twin == 'combined' else 'episodes'} {len(bad)}"
                      + "".join(f"\n    {e['kind']} {e['start_s']:.2f}-{e['end_s']:.2f} s "
                                f"{e['size_N']}" for e in bad), flush=True)
    print(f"pushes located {n_loc}/{n_push}, false episodes {n_false}, on the clean twins "
          f"{n_clean}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
