"""Study-free statistics: tests, intervals, bootstrap, power, the sequential design, variance
components and profiles, on plain arrays.

Nothing here knows models, scenarios or metrics; the report (`sigmarl.report`) brings those.
"""
