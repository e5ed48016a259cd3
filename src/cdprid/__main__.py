"""``python -m cdprid``: the ``cdprid`` command."""

import sys

from cdprid.cli import console_main

if __name__ == "__main__":
    sys.exit(console_main())
