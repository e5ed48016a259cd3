"""``cdprid differentiate``: first and second derivatives of the columns of a CSV file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["add_parser"]


def _run(args) -> int:
    from .cli import UserError, _parse_params
    from .differentiators import METHODS, differentiate
    from .io.dataset import read_csv_stream, sampling_report

    if args.method not in METHODS:
        raise UserError(f"unknown method {args.method!r}; choose one of {', '.join(METHODS)}.")
    params = _parse_params(args.params)
    cols, vals = read_csv_stream(Path(args.input), required=("t",))
    if len(cols) < 2:
        raise UserError(f"{args.input}: line 1 (header) has only 't'; add signal columns.")
    t = vals[:, cols.index("t")]
    if len(t) < 5:
        raise UserError(f"{args.input}: needs at least 5 samples, got {len(t)}.")
    rep = sampling_report(t)
    if not rep["uniform"]:
        raise UserError(
            f"{args.input}: column 't' is not uniformly sampled (max jitter "
            f"{100 * rep['max_jitter']:.1f} % of the period); resample it first."
        )
    names = [c for c in cols if c != "t"]
    y = vals[:, [cols.index(c) for c in names]]
    d1, d2 = differentiate(y, rep["dt"], method=args.method, **params)
    out = Path(args.out)
    if out.exists() and not args.force:
        raise FileExistsError(f"{out}: already exists; refusing to overwrite (use --force).")
    header = ["t"] + [f"{c}_d1" for c in names] + [f"{c}_d2" for c in names]
    with open(out, "w", encoding="utf-8") as fh:
        fh.write(",".join(header) + "\n")
        np.savetxt(fh, np.column_stack([t, d1, d2]), delimiter=",", fmt="%.17g")
    info = METHODS[args.method]
    print(f"{args.method} ({'causal' if info.causal else 'non-causal'}): {len(t)} samples, "
          f"{len(names)} column(s), dt = {rep['dt']:.6g} s -> wrote {out}")
    return 0


def add_parser(sub) -> None:
    """Register ``cdprid differentiate``."""
    from .differentiators import METHODS

    lines = [f"  {k:<20} {'causal' if v.causal else 'non-causal':<11} {v.description}"
             for k, v in METHODS.items()]
    import argparse

    p = sub.add_parser(
        "differentiate", help="estimate first and second derivatives of CSV columns",
        description="Differentiate every column of a CSV with a 't' column (uniform sampling). "
        "Output columns: t, <col>_d1 ..., <col>_d2 ....\n\nmethods:\n" + "\n".join(lines),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="CSV with a 't' column and signal columns")
    p.add_argument("--method", default="sihd2-cascade", help="differentiation method (see above)")
    p.add_argument("--params", help="method parameters as JSON, or a JSON file (e.g. from "
                   "`cdprid tune --json`)")
    p.add_argument("--out", required=True, help="output CSV")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.set_defaults(func=_run)
