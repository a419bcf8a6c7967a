"""``python -m steer_envs.bench``: same as the ``steer-bench`` console script."""

import sys

from steer_envs.bench.cli import main

sys.exit(main())
