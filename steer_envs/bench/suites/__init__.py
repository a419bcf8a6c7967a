"""The built-in suites of steer-bench: one module per small suite, one package per study.

``selftest`` (the runner's own check), ``smoke`` (experts and throughput on
every env), ``quick`` (the few-minute tour of every suite that declares quick
settings) and ``ltl`` (LTL translation time) are single modules; the thesis
studies are packages that keep the suite declarations (``suite.py``) apart
from the experiment protocols and figures: ``itps`` (ch. 2), ``tli`` (ch. 3)
and ``glide`` (ch. 4). Sibling suites do not import each other; helpers they
share live in :mod:`steer_envs.bench` or :mod:`steer_envs.utils`.
"""
