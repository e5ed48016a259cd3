"""``python -m cdprid``: the ``cdprid`` command."""

import sys

from cdprid.cli._main import main

if __name__ == "__main__":
    sys.exit(main())
