"""Initial and respawn states: batched rejection sampling with a spacing rule."""

from __future__ import annotations

import torch

from sigmarl.env.route_bank import RouteBank
from sigmarl.env.streams import SeedStreams
from sigmarl.errors import SigmarlError
from sigmarl.maps.model import RESAMPLE_STEP
from sigmarl.params import VEHICLE

MIN_GAP = 1.2 * VEHICLE.diagonal  # 0.2147 m
MAX_TRIES = 200


def capacity(routes: list) -> int:
    """An upper bound on how many vehicles a map's routes hold MIN_GAP apart: vehicles start on
    a route's center line, and points of one polyline MIN_GAP apart (straight) are at least
    MIN_GAP apart along it, so a route of length L holds at most L / MIN_GAP + 1. Routes that
    share lanes are counted twice, so the bound is loose but safe: more agents than this can
    never be placed, and are refused before the environment is built."""
    return sum(int(route.length / MIN_GAP) + 1 for route in routes)


def spawn_index_range(bank: RouteBank, train: bool, start_m: float, end_fraction: float,
                      margin_m: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Per route, the [lo, hi] center-line indices a vehicle may start at."""
    last = (bank.n_points - 1).to(torch.float32)
    if train:
        lo = torch.full_like(last, start_m / RESAMPLE_STEP)
        hi = last * end_fraction
    else:
        lo = torch.full_like(last, margin_m / RESAMPLE_STEP)
        hi = last - margin_m / RESAMPLE_STEP
    lo = torch.where(bank.is_loop, torch.zeros_like(lo), lo)
    hi = torch.where(bank.is_loop, last, hi)
    lo = lo.ceil().long()
    hi = hi.floor().long().maximum(lo)
    return lo, hi


def sample_spawns(
    bank: RouteBank,
    pos: torch.Tensor,
    place: torch.Tensor,
    lo: torch.Tensor,
    hi: torch.Tensor,
    streams: SeedStreams,
    route_choices: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """New (route, index) for the agents where `place` [E, A] is True.

    Candidates are drawn for all pending agents at once; a candidate is kept
    if it is MIN_GAP from every placed agent and from every other candidate.
    Returns route ids and point indices [E, A] (arbitrary where not placed).
    In a seed block (`streams` of S seeds, E = S x n) a seed draws candidates only while it
    still has agents to place, as it would alone.
    """
    device = pos.device
    n_env, n_agents = place.shape
    choices = route_choices if route_choices is not None else torch.arange(bank.n_routes, device=device)
    route = torch.zeros(n_env, n_agents, dtype=torch.long, device=device)
    index = torch.zeros_like(route)
    where = pos.clone()
    pending = place.clone()
    per_seed = (n_env // len(streams), n_agents)
    for _ in range(MAX_TRIES):
        if not pending.any():
            return route, index
        active = streams.active(pending)
        pick = streams.randint(len(choices), per_seed, active)
        r = choices[pick]
        u = streams.rand(per_seed, active)
        i = lo[r] + (u * (hi[r] - lo[r] + 1).to(u.dtype)).long().minimum(hi[r] - lo[r])
        cand = bank.center[r, i]
        trial = torch.where(pending.unsqueeze(-1), cand, where)
        d = torch.cdist(trial, trial)
        d = d + torch.eye(n_agents, device=device) * 1e9
        too_close = d < MIN_GAP
        # Pending agents clash with anyone close; placed agents never move.
        ok = pending & ~too_close.any(-1)
        route = torch.where(ok, r, route)
        index = torch.where(ok, i, index)
        where = torch.where(ok.unsqueeze(-1), cand, where)
        pending = pending & ~ok
    n_left = int(pending.sum(-1).max())  # in the worst environment
    raise SigmarlError(
        f"could not place {n_left} agent(s) {MIN_GAP:.4f} m apart from all others after "
        f"{MAX_TRIES} tries: the map cannot hold {n_agents} agents at that spacing; use fewer agents"
    )
