"""JSON on the command line: ``--params``/``--initial`` values and atomic JSON outputs.

The values are inline JSON or a JSON file; shared by the command modules.
"""

from __future__ import annotations

import json
from pathlib import Path

from cdprid.base import OutputError, UserError

__all__ = ["load_json_object", "parse_params", "write_json"]


def load_json_object(text: str, flag: str, expect: str) -> dict:
    """A JSON object given inline or as a file path; one-sentence UserError otherwise.

    Parameters
    ----------
    text : str
        Inline JSON (starting with ``{``) or the path of a JSON file.
    flag : str
        The option name, used in messages.
    expect : str
        What the object should be, e.g. ``"a JSON object such as '{\"cutoff_hz\": 4}'"``.

    Returns
    -------
    dict

    Raises
    ------
    UserError
        The file does not exist or cannot be read, the text is not JSON, or not an object.
    """
    src = "the value"
    if not text.lstrip().startswith(("{", "[")):
        p = Path(text)
        if not p.exists():
            raise UserError(f"{flag} {text}: the file does not exist (give a JSON file or an "
                            "inline JSON object).")
        if p.is_dir():
            raise UserError(f"{flag} {text}: is a folder, expected a JSON file.")
        try:
            text = p.read_text(encoding="utf-8-sig")
        except UnicodeDecodeError:
            raise UserError(f"{flag} {p}: not UTF-8 text.") from None
        except OSError as exc:
            raise UserError(f"{flag} {p}: cannot be read ({exc.strerror}).") from None
        src = str(p)
    try:
        val = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"{flag}: {src} is not valid JSON ({exc.msg} at line {exc.lineno}, "
                        f"column {exc.colno}).") from None
    if not isinstance(val, dict):
        raise UserError(f"{flag}: must be {expect}.")
    return val


def parse_params(text: str | None, flag: str = "--params") -> dict:
    """The differentiator parameters given as ``--params``: inline JSON or a JSON file.

    Parameters
    ----------
    text : str or None
        The option's value; None or empty gives ``{}``.
    flag : str
        The option name, used in messages.

    Returns
    -------
    dict
        The parameters; the output of ``cdprid tune --json`` (``{"method": ..., "params":
        {...}}``) gives its ``params``.

    Raises
    ------
    UserError
        See :func:`load_json_object`.
    """
    if not text:
        return {}
    val = load_json_object(text, flag, "a JSON object such as '{\"cutoff_hz\": 4}'")
    # accept the output of `cdprid tune --json` directly
    if "params" in val and isinstance(val["params"], dict) and "method" in val:
        val = val["params"]
    return val


def write_json(path, data: dict, force: bool = True) -> Path:
    """Write ``data`` as indented JSON atomically (creating the parent folder).

    Check the path with :func:`cdprid.base.check_output` before the work starts.

    Parameters
    ----------
    path : str or Path
        The JSON file.
    data : dict
        JSON-serialisable content.
    force : bool
        Replace an existing file.

    Returns
    -------
    Path
        The path written.
    """
    from cdprid.base import write_json as _write

    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out}: cannot create its folder ({exc.strerror}).") from None
    return _write(out, data, force=force)


