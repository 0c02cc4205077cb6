"""The paper's code where ours differs, as config keys (`rules.*`), one switch per difference.
`sigmarl.env.paper_rules` carries them out; `conf/rules/*.yaml` turns them on by family."""

from __future__ import annotations

from dataclasses import dataclass

# Switches added after runs were first trained under `rules=paper`: off in every earlier run
# (their fingerprints leave them out at that value, `sigmarl.identity.ADDED_LATER`).
ADDED_KEYS = {"rules.reward_normaliser_one": False, "rules.reset_speed_one": False}


@dataclass
class RulesConfig:
    """The paper's code where ours differs, one switch per difference: all off (`rules=ours`)
    is our environment, all on (`rules=paper`) the paper's. Evaluation keeps the dynamics and
    observation switches of the checkpoint it evaluates; it always measures with our
    contacts, per-agent flags and fresh observations (`sigmarl.env.paper_rules`)."""

    # VMAS drag 0.25 makes v = delta/dt - 0.25 v_prev: steady 0.8 c through an alternating
    # transient c, 0.75 c, 0.81 c, ...; the yaw rate likewise
    drag_dynamics: bool = False
    """Paper: speed command in [-1, 1] through VMAS's drag (steady 0.8 of the command)."""
    speed_normaliser_one: bool = False
    """Paper: observed speeds and velocities divided by 1.0 (ours by 0.8)."""
    unsigned_speed: bool = False
    """Paper: the ego view observes |v| (ours the signed forward speed)."""
    others_velocity_heading: bool = False
    """Paper: another's velocity observed as |v_j| (cos, sin)(psi_j - psi_i), along its heading, unsigned."""
    unwrapped_headings: bool = False
    """Paper: headings and relative headings never wrapped to (-pi, pi]."""
    one_sided_noise: bool = False
    """Paper: noise + obs.noise x U[0, 1) (mean +0.01; ours zero-mean)."""
    raw_center_line: bool = False
    """Paper: center line at raw map vertices; reference points the vertices +2, +4, +6 from the closest segment."""
    own_boundary_index: bool = False
    """Paper (M4): 5 raw boundary vertices from the boundary's own closest segment (ours: resampled)."""
    test_world_size: bool = False
    """Paper: the bird's-eye view normalised by the test map's size in evaluation."""
    strict_crossings: bool = False
    """Paper: a collision is a strict crossing of edges; touching and containment do not count."""
    env_lane_flag: bool = False
    """Paper: the lane-collision info flag is per environment (ours per agent)."""
    lagged_steering: bool = False
    """Paper: the steering penalty on delta_{t-1} - delta_{t-2} (ours delta_t - delta_{t-1})."""
    timeout_terminal: bool = False
    """Paper: a training time-out is terminal (ours: truncated, bootstrapped)."""
    stale_respawn_obs: bool = False
    """Paper: test-mode respawns return the pre-respawn observation."""
    reward_normaliser_one: bool = False
    """Paper: the reward's motion terms (progress, speed, moving) divided by 1.0 m/s (ours by 0.8)."""
    reset_speed_one: bool = False
    """Paper: a respawned vehicle's speed drawn in [0, 1.0) m/s (ours in [0, env.vehicle.max_speed))."""
