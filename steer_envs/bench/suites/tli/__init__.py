"""TLI / LTL-DS suites (thesis ch. 3): single-mode invariance, soup scooping under pushes, LPV-DS fit time.

``suite`` declares ``tli-single-mode``, ``tli-scoop`` and ``tli-ds-fit``;
``protocol`` runs the single-mode study (fits, rollouts, the cut loop),
``robustness`` the soup-scooping experiments, ``plots`` their figures.
"""
