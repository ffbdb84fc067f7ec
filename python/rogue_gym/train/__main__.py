"""``python -m rogue_gym.train``: see :mod:`rogue_gym.train.cli`."""

import sys

from .cli import main

sys.exit(main())
