"""GLiDE suites on PolygonNav (thesis ch. 4): mode grounding with ablations, and Table 4.1's policies.

``suite`` declares ``glide-polygon-grounding`` and ``glide-polygon`` (their
trials call :mod:`steer_envs.baselines.glide`); ``plots`` draws learned mode
boundaries.
"""
