"""``python -m steer_envs.baselines.training``: the training CLI (see :mod:`.trainer`)."""

from steer_envs.baselines.training.trainer import main

raise SystemExit(main())
