"""``python -m arap.cli``: the ``arap`` command."""

import sys

from arap.cli import main

if __name__ == "__main__":  # not when imported (e.g. by a walk over the package's modules)
    sys.exit(main())
