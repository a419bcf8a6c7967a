"""``sb3`` (issue #21): stable-baselines3 SAC with its defaults on the dense 2D envs, SAC + HER on goal Maze2D.

``suite`` declares the suite (parameters, metrics, the issue's thresholds and
findings), ``protocol`` trains and evaluates one agent (resumably, under a
cache folder), ``plots`` draws the learning curves.
"""
