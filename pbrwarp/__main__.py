"""``python -m pbrwarp``: the same command line as the ``pbrwarp`` script."""

import sys

from .cli import main

sys.exit(main())
