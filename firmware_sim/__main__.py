"""``python -m firmware_sim``: same as the ``firmware-sim`` console script."""
import sys

from .cli import main

sys.exit(main())
