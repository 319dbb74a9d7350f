"""``python -m ceco_bringup.sweep GRID.yaml --out DIR`` (= ``ceco sweep``)."""

import sys

from .cli import main

sys.exit(main())
