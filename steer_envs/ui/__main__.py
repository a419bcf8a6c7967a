"""``python -m steer_envs.ui`` runs ``steer-ui``."""

import sys

from steer_envs.ui.cli import main

sys.exit(main())
