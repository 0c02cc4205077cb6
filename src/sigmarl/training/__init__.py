"""MAPPO training (torchrl): networks, the loop, checkpoints."""

from sigmarl.training.loop import TrainResult, load_policy, train

__all__ = ["TrainResult", "load_policy", "train"]
