"""Traffic environment: a batched VMAS scenario (dynamics, observation, reward, collisions, resets)."""

from sigmarl.env.factory import make_env

__all__ = ["make_env"]
