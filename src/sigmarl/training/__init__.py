"""MAPPO training (torchrl): networks, the loop (one seed, or a block of seeds), checkpoints."""

from sigmarl.training.loop import TrainResult, load_policy, train, train_block

__all__ = ["TrainResult", "load_policy", "train", "train_block"]
