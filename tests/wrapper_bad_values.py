"""Hypothesis strategies of values no wrapper boundary may take as a number, a vector or a bool; the sampler knobs."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import strategies as st

from steer_envs.steering import BiasedInitialization, GuidedDiffusion, OutputPerturbation, Sampler, StochasticSampling

#: the samplers' numeric knobs, each with the sampler class that takes it
SAMPLER_KNOBS: dict[str, type[Sampler]] = {
    "guide_ratio": GuidedDiffusion,
    "min_guided_t": GuidedDiffusion,
    "mcmc_steps": StochasticSampling,
    "start_t": BiasedInitialization,
    "init_std": BiasedInitialization,
    "index": OutputPerturbation,
}

#: scalars that are not real numbers (or not finite): each must be refused, never converted
NOT_REAL = st.one_of(
    st.text(max_size=6),  # "0.5", "1", "False", ""
    st.sampled_from(["0.5", "1", "nan", "False", "True", "-1e9"]),
    st.complex_numbers(allow_nan=False, allow_infinity=False).filter(lambda z: z.imag != 0),
    st.booleans(),
    st.none(),
    st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
    st.just(object()),
)
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf, np.float32("nan"), np.float64("inf")])


def bad_vectors(dim: int) -> st.SearchStrategy[object]:
    """Things that are not a finite real vector of shape ``(dim,)``."""
    good = st.lists(st.floats(-5, 5), min_size=dim, max_size=dim)
    return st.one_of(
        NOT_REAL,
        NON_FINITE,
        good.map(lambda v: [str(x) for x in v]),  # numbers as strings
        good.map(lambda v: np.asarray(v) + 1j),  # complex
        good.map(lambda v: [*v[:-1], math.nan]),  # a NaN inside
        good.map(lambda v: [*v[:-1], math.inf]),
        st.lists(st.floats(-5, 5), min_size=0, max_size=5).filter(lambda v: len(v) != dim),  # wrong length
        good.map(lambda v: [v, v]),  # wrong rank
        good.map(lambda v: [bool(x > 0) for x in v]),  # booleans
        st.just([[1.0, 2.0], [3.0]]),  # ragged
    )


#: sensor readings that are not a real bool (``bool()`` would make most of them True)
NOT_BOOL = st.one_of(
    st.sampled_from(["False", "True", "", "0", "no"]),
    st.sampled_from([math.nan, 0, 1, 0.0, 1.0, -1, 2]),
    st.none(),
    st.just([True]),
    st.just(np.array([True, False])),
)
