"""Study-free statistics on plain arrays: the comparison engine (`engine`) and the seed-aware
bootstrap, profiles, variance components and intervals (`bootstrap`).

Nothing here knows models, scenarios or metrics; the report (`sigmarl.report`) brings those.
"""
