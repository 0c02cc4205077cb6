"""Random streams of a seed block: one generator per seed, each drawing for its own slice of
the environments.

A scenario that holds S seeds' environments ([S * E, ...], seed k's rows k*E .. (k+1)*E) draws
every random number of seed k from seed k's generator, with the shape a lone run of that seed
draws (`[E, ...]`), and only when a lone run would draw it. Seed k of a block therefore sees the
spawns and the noise it would see alone; with S = 1 every draw is the one-generator draw it
always was (same calls, same bits).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch


class SeedStreams:
    """S generators on one device, seeded together, drawing [S * n, ...] tensors seed by seed."""

    def __init__(self, n_seeds: int, device: torch.device | str) -> None:
        if n_seeds < 1:
            raise ValueError(f"a block holds at least one seed, got {n_seeds}")
        self.device = torch.device(device)
        self.generators = [torch.Generator(device=self.device) for _ in range(n_seeds)]

    def __len__(self) -> int:
        return len(self.generators)

    def seed(self, seeds: Sequence[int]) -> None:
        if len(seeds) != len(self.generators):
            raise ValueError(f"{len(self.generators)} streams, {len(seeds)} seeds")
        for g, s in zip(self.generators, seeds, strict=True):
            g.manual_seed(int(s))

    def active(self, mask: torch.Tensor) -> list[bool] | None:
        """Which seeds a draw for `mask` [S * n, ...] concerns (any True in its rows), or None
        for all of them. One host sync, and none for a lone seed: its callers only draw when
        the mask holds something, as they always did."""
        if len(self.generators) == 1:
            return None
        return mask.reshape(len(self.generators), -1).any(-1).tolist()

    def rand(self, shape: Sequence[int], active: list[bool] | None = None) -> torch.Tensor:
        """U[0, 1) of shape [S * shape[0], *shape[1:]], `shape` being one seed's (zeros for the
        seeds `active` leaves out, which draw nothing)."""
        return self._draw(lambda g: torch.rand(tuple(shape), generator=g, device=self.device), shape,
                          torch.float32, active)

    def randint(self, high: int, shape: Sequence[int], active: list[bool] | None = None) -> torch.Tensor:
        return self._draw(lambda g: torch.randint(high, tuple(shape), generator=g, device=self.device),
                          shape, torch.long, active)

    def randn(self, shape: Sequence[int], active: list[bool] | None = None) -> torch.Tensor:
        return self._draw(lambda g: torch.randn(tuple(shape), generator=g, device=self.device), shape,
                          torch.float32, active)

    def _draw(self, draw, shape, dtype, active) -> torch.Tensor:
        if len(self.generators) == 1:
            return draw(self.generators[0])
        parts = [draw(g) if active is None or active[k] else torch.zeros(tuple(shape), dtype=dtype,
                                                                        device=self.device)
                 for k, g in enumerate(self.generators)]
        return torch.cat(parts)
