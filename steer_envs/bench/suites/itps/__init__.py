"""``itps-maze2d`` (thesis ch. 2, Table 2.1): inference-time steering of DP and ACT with sketches in Maze2D.

``suite`` declares the suite (parameters, metrics, the thesis's numbers and
findings; a trial is :func:`steer_envs.steering.maze.steering_trial`),
``scaling`` the DP scaling pilots, ``plots`` draws the trade-off and
qualitative figures.
"""
