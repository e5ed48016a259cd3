"""Episodes (issue 38) on push-free recordings of the floor-winch 8-cable robot: false
episodes left by the load-cell effects that persist over a recording.

``tests._testbench.floor8_case`` (the independent test simulator): 45-55 s, Coulomb friction of
1-3 N on every pulley (cells on the winch side), a hysteretic cell of 2-4 N on even seeds, a
12-28 ms clock offset on three seeds of four, an offset, a gain on odd seeds, drag or a 3 cm
exit-point error on some. No push: every episode the stage reports is false. The stage runs as
``cdprid identify`` calls it (:func:`cdprid.episodes.find_episodes` on the whole aligned
recording, its default trim and cutoff).

Run from the repository root::

    python -m benchmarks.episodes_floor8 [--seeds 0-13] [--workdir /tmp/floor8]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def run(seeds, workdir: Path) -> list:
    """``[(seed, duration s, episodes, caveat)]`` for each seed."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from tests._testbench import floor8_case, write

    from cdprid.episodes import find_episodes, winch_lengths
    from cdprid.io import align, read_dataset

    out = []
    for seed in seeds:
        d = workdir / f"floor8-{seed}"
        if not (d / "robot.toml").exists():
            write(floor8_case(seed), d, overwrite=True)
        ds = read_dataset(d)
        sig = align(ds)
        eps = find_episodes(ds.robot, sig, lengths=winch_lengths(ds, sig.t))
        dur = float(sig.t[-1] - sig.t[0])
        out.append((seed, dur, eps.episodes, eps.caveat))
        print(f"seed {seed}: {dur:.1f} s, {len(eps.episodes)} episode(s)"
              + "".join(f"\n    {e.describe()}" for e in eps.episodes)
              + (f"\n    caveat: {eps.caveat}" if eps.caveat else ""), flush=True)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", default="0-13", help="a range 0-13 or a list 0,2,4")
    p.add_argument("--workdir", default="/tmp/cdprid-floor8-episodes")
    a = p.parse_args(argv)
    if "-" in a.seeds:
        lo, hi = (int(x) for x in a.seeds.split("-"))
        seeds = list(range(lo, hi + 1))
    else:
        seeds = [int(x) for x in a.seeds.split(",")]
    t0 = time.perf_counter()
    res = run(seeds, Path(a.workdir))
    hours = sum(r[1] for r in res) / 3600.0
    n = sum(len(r[2]) for r in res)
    withheld = sum(r[3] is not None for r in res)
    print(f"{len(res)} recordings, {hours:.3f} h, {n} false episode(s) ({n / hours:.1f} per hour), "
          f"{withheld} recording(s) whose wrench episodes were withheld as not local; "
          f"{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
