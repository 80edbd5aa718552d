"""``python -m copdea_fem.sweep benchmark SWEEP.yaml``: the sweep benchmark."""

import sys

from .benchmark import main

sys.exit(main(sys.argv[1:]))
