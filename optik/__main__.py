"""``python -m optik``: the ``optik`` command, for an environment whose scripts are not on PATH."""

import sys

from optik.cli import main

if __name__ == "__main__":
    sys.exit(main())
