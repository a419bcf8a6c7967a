"""``python -m steer_envs.baselines.training``: the training CLI (see :mod:`.cli`)."""

from steer_envs.baselines.training.cli import main

raise SystemExit(main())
