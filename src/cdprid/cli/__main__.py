"""``python -m cdprid.cli``: the ``cdprid`` command (same as ``python -m cdprid``)."""

import sys

from cdprid.cli._main import console_main

if __name__ == "__main__":
    sys.exit(console_main())
