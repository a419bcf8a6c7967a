"""``python -m steer_envs.baselines.training``: the training CLI."""

from steer_envs.baselines.training.trainer import main

raise SystemExit(main())
