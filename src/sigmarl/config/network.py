"""The actor and critic networks (`network.*`, conf/network/*.yaml)."""

from __future__ import annotations

from dataclasses import dataclass

from sigmarl.config.ranges import ranged


@dataclass
class NetworkConfig:
    """The actor and critic MLPs (the paper's: 256x256 tanh, a centralised critic: MAPPO)."""

    hidden: list[int] = ranged(factory=lambda: [256, 256], lo=1, hi=65536, size=True)
    """hidden layer sizes of the actor and of the critic"""
    activation: str = ranged("tanh", choices=("tanh", "relu", "elu"))
    """the hidden layers' activation: tanh | relu | elu"""
    scale_floor: float = ranged(1e-4, lo=0, lo_open=True)
    """the smallest standard deviation of the policy's Gaussian"""
    centralised_critic: bool = True
    """true (MAPPO, the paper's): the critic sees all agents' observations; false (IPPO): each agent's value from its own observation only"""
    shared_critic_value: bool = True
    """true (the paper's): one critic network for all agents (centralised: one value, copied to each); false: one output head (centralised) or one network (decentralised) per agent"""
