"""GLiDE suites on PolygonNav (thesis ch. 4): mode grounding with ablations, and Table 4.1's policies.

``suite`` declares ``glide-polygon-grounding`` and ``glide-polygon``;
``protocol`` builds the data sets, trains and caches the classifiers and
evaluates the policies; ``plots`` draws learned mode boundaries.
"""
