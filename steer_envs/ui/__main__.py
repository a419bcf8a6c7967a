"""``python -m steer_envs.ui`` runs ``steer-ui``."""

import sys

from steer_envs.ui.cli import main

if __name__ == "__main__":
    sys.exit(main())
