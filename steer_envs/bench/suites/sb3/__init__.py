"""``sb3``: stable-baselines3 SAC with its defaults on the dense 2D envs, SAC + HER on goal Maze2D.

``suite`` declares the suite (parameters, metrics, the RL-readiness targets and
findings) and calls :func:`steer_envs.baselines.sb3.train_and_evaluate` per
trial (resumably, under a cache folder); ``plots`` draws the learning curves.
"""
