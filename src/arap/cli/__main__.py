"""``python -m arap.cli``: the ``arap`` command."""

import sys

from arap.cli import main

sys.exit(main())
