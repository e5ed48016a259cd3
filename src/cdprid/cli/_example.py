"""``cdprid example --out DIR``: write the package's sample dataset for a first run.
"""

from __future__ import annotations

__all__ = ["configure"]


def _cmd_example(args) -> int:
    from cdprid.base import check_output
    from cdprid.data import write_sample

    check_output(args.out, args.force, "--out", kind="dir")
    out = write_sample(args.out, args.name, force=args.force)
    print(f"wrote {out} (simulated 8-cable robot with rotation; truth in meta.toml [truth])")
    print(f"next: cdprid identify {out} --model full")
    return 0


def configure(p) -> None:
    """Give the ``example`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it)."""
    from cdprid.data import SAMPLES

    p.description = ("Write the package's small simulated sample dataset (spec v1, truth in "
                     "meta.toml) into a new folder.")
    p.add_argument("--out", required=True, help="dataset folder to create")
    p.add_argument("--name", default="sample-8cable", choices=sorted(SAMPLES),
                   help="which sample (default sample-8cable)")
    p.add_argument("--force", action="store_true", help="replace an existing --out")
    p.set_defaults(func=_cmd_example)
