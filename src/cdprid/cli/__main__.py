"""``python -m cdprid.cli``: the ``cdprid`` command (same as ``python -m cdprid``)."""

import sys

from cdprid.cli._main import main

if __name__ == "__main__":
    sys.exit(main())
