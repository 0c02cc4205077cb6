"""MAPPO's budget and update (`ppo.*`, conf/ppo/*.yaml)."""

from __future__ import annotations

from dataclasses import dataclass

from sigmarl.config.ranges import ranged


@dataclass
class PPOConfig:
    """MAPPO's training budget and update (the paper's settings by default)."""

    iterations: int = ranged(250, lo=1)
    """Training iterations (collection + update)."""
    frames_per_iteration: int = ranged(4096, lo=1, hi=2**30, size=True)
    """Frames collected per iteration: num_envs x rollout steps (128, one training episode)."""
    num_envs: int = ranged(32, lo=1, hi=2**20, size=True)
    """Parallel environments while training."""
    epochs: int = ranged(60, lo=1)
    """PPO epochs over each iteration's frames."""
    minibatch_size: int = ranged(512, lo=1, hi=2**30, size=True)
    """Frames per minibatch of the PPO update."""
    lr: float = ranged(2e-4, lo=0)
    """Learning rate at the first iteration (linear decay to lr_final)."""
    lr_final: float = ranged(1e-5, lo=0)
    """Learning rate at the last iteration."""
    max_grad_norm: float = ranged(1.0, lo=0)
    """Gradients are clipped to this norm."""
    clip_epsilon: float = ranged(0.2, lo=0, hi=1, lo_open=True, hi_open=True)
    """PPO's clipping of the probability ratio."""
    gamma: float = ranged(0.99, lo=0, hi=1)
    """Discount factor."""
    lmbda: float = ranged(0.9, lo=0, hi=1)
    """GAE's lambda."""
    entropy_coef: float = ranged(1e-4, lo=0)
    """Weight of the entropy bonus in the loss."""
    normalize_advantage: bool = False
    """Normalise advantages per minibatch."""
    loss: str = ranged("lean", choices=("lean",))
    """lean: the PPO loss on plain tensors (the one loss; checked against torchrl's ClipPPOLoss in the tests)."""
    precision: str = ranged("fp32", choices=("fp32", "bf16", "auto"))
    """fp32 | bf16: the update's forward passes under bfloat16 autocast | auto: bf16 where native."""
    # bf16 keeps log-probabilities, ratios, advantages and losses in fp32; auto picks bf16 where
    # the CPU has native bf16 (avx512_bf16 / amx_bf16) or the GPU supports it
    checkpoint_every: int = ranged(5, lo=1)
    """Write the resume point checkpoint.pt every this many iterations."""
    stop_after: int = ranged(0, lo=0)
    """>0: stop (as if interrupted, resumable) once this many iterations are done."""
