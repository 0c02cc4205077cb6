"""What a policy observes (`obs.*`, conf/obs/<preset>.yaml): a flag per declared strategy and
the vector's sizes."""

from __future__ import annotations

from dataclasses import dataclass

from sigmarl.ablation import strategy_flags
from sigmarl.config.ranges import ranged


@dataclass
class ObsConfig(strategy_flags()):  # a flag per declared strategy (`sigmarl.ablation.STRATEGIES`)
    """Observation design: the strategies as flags (the paper's five on, any later one off = M0)."""

    preset: str = "full"
    """The conf/obs preset this started from (full, no_ego_view, ...); only a starting point, the flags decide."""
    n_nearest: int = ranged(2, lo=0, hi=1024, size=True)
    """K: how many nearest other vehicles are observed."""
    n_ref_points: int = ranged(3, lo=1, hi=3)
    """How many short-term reference points on the center line are observed."""
    ref_point_stride: int = ranged(2, lo=1, hi=6)
    """Resampled center-line points between reference points (2 x 0.08 m)."""
    noise: float = ranged(0.02, lo=0)
    """Total width of the zero-mean uniform noise added to every observation entry."""
