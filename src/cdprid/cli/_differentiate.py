"""``cdprid differentiate``: first and second derivatives of the columns of a CSV file."""

from __future__ import annotations

from pathlib import Path

__all__ = ["configure"]


def _run(args) -> int:
    import numpy as np

    from cdprid.base import Progress, UserError, atomic_file, check_output
    from cdprid.cli._json_args import parse_params
    from cdprid.io import read_csv_stream, sampling_report

    out = check_output(args.out, force=args.force, flag="--out", inputs=[args.input])
    params = parse_params(args.params)
    from cdprid.signal import METHODS, differentiate

    if args.method not in METHODS:
        raise UserError(f"--method: unknown method {args.method!r}; choose one of "
                        f"{', '.join(METHODS)}.")
    prog = Progress("differentiate")
    cols, vals = read_csv_stream(Path(args.input), required=("t",))
    if len(cols) < 2:
        raise UserError(f"{args.input}: line 1 (header) has only 't'; add signal columns.")
    t = vals[:, cols.index("t")]
    if len(t) < 5:
        raise UserError(f"{args.input}: needs at least 5 samples, got {len(t)}.")
    rep = sampling_report(t)
    if not rep["uniform"]:
        raise UserError(
            f"{args.input}: column 't' is not uniformly sampled (max deviation of a period "
            f"{100 * rep['max_jitter']:.1f} % of the median {rep['dt']:.4g} s); gaps are never "
            "bridged: split the file at the gaps or resample it first."
        )
    names = [c for c in cols if c != "t"]
    y = vals[:, [cols.index(c) for c in names]]
    prog.say(f"read {len(t)} samples x {len(names)} column(s); differentiating")
    try:
        d1, d2 = differentiate(y, rep["dt"], method=args.method, **params)
    except TypeError as exc:  # an unknown parameter name in --params
        raise UserError(f"--params: {exc}.") from None
    header = ["t"] + [f"{c}_d1" for c in names] + [f"{c}_d2" for c in names]
    prog.say(f"writing {out}")
    with atomic_file(out, "w", force=args.force) as fh:
        fh.write(",".join(header) + "\n")
        np.savetxt(fh, np.column_stack([t, np.asarray(d1), np.asarray(d2)]), delimiter=",",
                   fmt="%.17g")
    info = METHODS[args.method]
    print(f"{args.method} ({'causal' if info.causal else 'non-causal'}): {len(t)} samples, "
          f"{len(names)} column(s), dt = {rep['dt']:.6g} s -> wrote {out}")
    return 0


def _methods_description() -> str:
    from cdprid.signal import METHODS

    lines = [f"  {k:<20} {'causal' if v.causal else 'non-causal':<11} {v.description}"
             for k, v in METHODS.items()]
    return ("Differentiate every column of a CSV with a 't' column (uniform sampling; a file "
            "with gaps is refused, never bridged). Output columns: t, <col>_d1 ..., <col>_d2 "
            "....\n\nmethods:\n" + "\n".join(lines))


def configure(p) -> None:
    """Give the ``differentiate`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it); the method table is built only for its --help."""
    import argparse

    from cdprid.cli._types import existing_file, json_or_file

    p.description = "Differentiate every column of a CSV with a 't' column."
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    format_help = p.format_help

    def _format_help() -> str:  # the method table imports JAX: only when help is asked for
        p.description = _methods_description()
        return format_help()

    p.format_help = _format_help
    p.add_argument("input", type=existing_file, help="CSV with a 't' column and signal columns")
    p.add_argument("--method", default="sihd2-cascade", help="differentiation method (see above)")
    p.add_argument("--params", type=json_or_file, help="method parameters as JSON, or a JSON "
                   "file (e.g. from `cdprid tune --json`)")
    p.add_argument("--out", required=True, help="output CSV (written whole or not at all)")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.set_defaults(func=_run)
