"""TLI / LTL-DS suites (thesis ch. 3): single-mode invariance, soup scooping under pushes, LPV-DS fit time.

``suite`` declares ``tli-single-mode``, ``tli-scoop`` and ``tli-ds-fit``;
``protocol`` and ``robustness`` hold their trial functions (the fits,
rollouts, cut loop and pushed episodes they call live in
:mod:`steer_envs.baselines.lpv_ds`, the demonstrations and push schedules in
:mod:`steer_envs.data`), ``plots`` their figures.
"""
