"""Kinematic bicycle step against hand-worked values, circle fits and a fine RK4 integration."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from sigmarl.env.dynamics import bicycle_step, slip_angle

F64 = torch.float64
L, LR, DT = 0.16, 0.08, 0.05


def turning_radius(steering: torch.Tensor, l_r: float = LR, wheelbase: float = L) -> torch.Tensor:
    """Radius of the circle the centre of gravity drives at constant steering (inf at delta=0)."""
    beta = slip_angle(steering, l_r, wheelbase)
    return wheelbase / (torch.cos(beta) * torch.tan(steering))


def t64(x) -> torch.Tensor:
    return torch.tensor(x, dtype=F64)


def rollout(pos, heading, speed, steering, steps, dt=DT):
    """Positions [steps+1, ..., 2] and headings [steps+1, ...] of a constant-input run."""
    ps, hs = [pos], [heading]
    for _ in range(steps):
        pos, heading, _ = bicycle_step(pos, heading, speed, steering, dt)
        ps.append(pos)
        hs.append(heading)
    return torch.stack(ps), torch.stack(hs)


def fit_circle(xy: torch.Tensor) -> tuple[torch.Tensor, float]:
    """Algebraic least-squares circle x^2 + y^2 + Dx + Ey + F = 0 through points [N, 2]."""
    x, y = xy[:, 0], xy[:, 1]
    A = torch.stack([x, y, torch.ones_like(x)], dim=1)
    sol = torch.linalg.lstsq(A, -(x**2 + y**2)[:, None]).solution[:, 0]
    center = -sol[:2] / 2
    return center, math.sqrt(float(center @ center - sol[2]))


def ode(state: torch.Tensor, speed, steering) -> torch.Tensor:
    """Right-hand side of the model, state = (x, y, psi)."""
    beta = torch.atan(LR / L * torch.tan(steering))
    psi = state[..., 2]
    return torch.stack(
        (
            speed * torch.cos(psi + beta),
            speed * torch.sin(psi + beta),
            speed / L * torch.cos(beta) * torch.tan(steering),
        ),
        dim=-1,
    )


def rk4(state, speed, steering, dt, substeps=200):
    h = dt / substeps
    for _ in range(substeps):
        k1 = ode(state, speed, steering)
        k2 = ode(state + h / 2 * k1, speed, steering)
        k3 = ode(state + h / 2 * k2, speed, steering)
        k4 = ode(state + h * k3, speed, steering)
        state = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return state


def test_turning_radius_hand_value():
    # beta = atan(0.5 tan 35 deg) = 0.336767 rad; R = 0.16 / (cos(beta) tan 35 deg) = 0.242103 m
    # (equivalently l_r / sin(beta)).
    assert turning_radius(t64(math.radians(35))).item() == pytest.approx(0.242103, abs=1e-6)
    assert math.isinf(turning_radius(t64(0.0)).item())
    assert turning_radius(t64(-0.3)).item() == pytest.approx(-turning_radius(t64(0.3)).item())


@pytest.mark.parametrize("heading", [0.0, 0.7, -2.5, math.pi])
def test_straight_driving_covers_v_dt_per_step(heading):
    pos, h = rollout(t64([1.0, -2.0]), t64(heading), t64(0.6), t64(0.0), steps=20)
    direction = t64([math.cos(heading), math.sin(heading)])
    for k in range(21):
        torch.testing.assert_close(pos[k], t64([1.0, -2.0]) + k * 0.6 * DT * direction)
    torch.testing.assert_close(h, torch.full_like(h, heading), atol=1e-15, rtol=0)
    _, _, vel = bicycle_step(t64([0.0, 0.0]), t64(heading), t64(0.6), t64(0.0))
    torch.testing.assert_close(vel, 0.6 * direction)


def test_reverse_moves_backwards():
    pos, heading, vel = bicycle_step(t64([0.0, 0.0]), t64(0.0), t64(-0.5), t64(0.0))
    torch.testing.assert_close(pos, t64([-0.5 * DT, 0.0]))
    torch.testing.assert_close(vel, t64([-0.5, 0.0]))
    # Reversing with the wheels turned left: the nose swings right (heading decreases) and
    # the car backs away to its right (x and y both decrease from heading 0).
    pos, heading, _ = bicycle_step(t64([0.0, 0.0]), t64(0.0), t64(-0.5), t64(0.5))
    assert heading.item() < 0 and pos[0].item() < 0 and pos[1].item() < 0
    fwd_pos, fwd_heading, _ = bicycle_step(t64([0.0, 0.0]), t64(0.0), t64(0.5), t64(0.5))
    assert fwd_heading.item() == pytest.approx(-heading.item())


@pytest.mark.parametrize(("speed", "steer_deg"), [(0.8, 35.0), (0.8, -35.0), (-0.5, 35.0)])
def test_constant_steering_traces_the_turning_circle(speed, steer_deg):
    steering = t64(math.radians(steer_deg))
    pos, _ = rollout(t64([2.0, 1.0]), t64(0.4), t64(speed), steering, steps=40)
    center, radius = fit_circle(pos)
    expected = abs(turning_radius(steering).item())
    assert radius == pytest.approx(expected, abs=1e-6)
    assert radius == pytest.approx(0.242103, abs=1e-6)
    # Every point lies on that circle, and the centre is on the side the car turns to.
    torch.testing.assert_close((pos - center).norm(dim=1), torch.full((41,), radius, dtype=F64))
    start_to_center = center - t64([2.0, 1.0])
    left = t64([-math.sin(0.4), math.cos(0.4)])
    assert math.copysign(1.0, float(start_to_center @ left)) == math.copysign(1.0, steer_deg)


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-math.pi, math.pi),
    st.floats(-0.8, 0.8),
    st.floats(-math.radians(35), math.radians(35)),
)
def test_exact_step_matches_fine_rk4(heading, speed, steering):
    pos, h, vel = bicycle_step(t64([0.3, -0.2]), t64(heading), t64(speed), t64(steering))
    ref = rk4(t64([0.3, -0.2, heading]), t64(speed), t64(steering), DT, substeps=50)
    torch.testing.assert_close(pos, ref[:2], atol=1e-9, rtol=0)
    dpsi = math.remainder(h.item() - ref[2].item(), 2 * math.pi)
    assert abs(dpsi) < 1e-9
    # The velocity is the model's (x', y') at the end state.
    torch.testing.assert_close(vel, ode(ref, t64(speed), t64(steering))[:2], atol=1e-9, rtol=0)


def test_exact_step_matches_fine_rk4_batched_extremes():
    # Full-lock and full-speed combinations plus a random batch, in one vectorised call.
    g = torch.Generator().manual_seed(4)
    lock, vmax = math.radians(35), 0.8
    extremes = t64([[s, d] for s in (-vmax, vmax) for d in (-lock, 0.0, lock)])
    rand = (torch.rand(200, 2, generator=g, dtype=F64) * 2 - 1) * t64([vmax, lock])
    speed, steering = torch.cat([extremes, rand]).unbind(-1)
    heading = (torch.rand(speed.shape, generator=g, dtype=F64) * 2 - 1) * math.pi
    pos = torch.rand(*speed.shape, 2, generator=g, dtype=F64) * 4
    new_pos, new_heading, _ = bicycle_step(pos, heading, speed, steering)
    ref = rk4(torch.cat([pos, heading[:, None]], dim=1), speed, steering, DT, substeps=400)
    torch.testing.assert_close(new_pos, ref[:, :2], atol=1e-10, rtol=0)
    dpsi = torch.remainder(new_heading - ref[:, 2] + math.pi, 2 * math.pi) - math.pi
    assert dpsi.abs().max().item() < 1e-10


def test_tiny_steering_is_smooth_and_finite():
    # omega -> 0 must approach straight driving without 0/0.
    for steer in (0.0, 1e-12, 1e-8, -1e-6):
        pos, h, vel = bicycle_step(t64([0.0, 0.0]), t64(0.0), t64(0.8), t64(steer))
        assert torch.isfinite(pos).all() and torch.isfinite(vel).all()
        ref = rk4(t64([0.0, 0.0, 0.0]), t64(0.8), t64(steer), DT, substeps=10)
        torch.testing.assert_close(pos, ref[:2], atol=1e-15, rtol=0)
        torch.testing.assert_close(h, ref[2], atol=1e-15, rtol=0)
    pos, h, vel = bicycle_step(t64([1.0, 1.0]), t64(0.5), t64(0.0), t64(0.6))
    torch.testing.assert_close(pos, t64([1.0, 1.0]), atol=0, rtol=0)
    assert h.item() == 0.5 and torch.equal(vel, t64([0.0, 0.0]))


@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_heading_stays_wrapped_over_long_runs(dtype):
    E, A, steps = 2, 3, 3000
    pos = torch.zeros(E, A, 2, dtype=dtype)
    heading = torch.zeros(E, A, dtype=dtype)
    speed = torch.tensor([[0.8, -0.8, 0.3], [0.5, 0.8, -0.2]], dtype=dtype)
    steering = torch.tensor([[0.6, 0.6, -0.2], [-0.6, 0.1, 0.6]], dtype=dtype)
    pi = torch.tensor(math.pi, dtype=dtype)
    for _ in range(steps):
        pos, heading, _ = bicycle_step(pos, heading, speed, steering)
        assert ((heading > -pi) & (heading <= pi)).all()
    # Wrapping does not lose turns: the heading equals steps * omega * dt modulo 2 pi.
    beta = torch.atan(0.5 * torch.tan(steering.double()))
    total = steps * DT * speed.double() / L * torch.cos(beta) * torch.tan(steering.double())
    diff = torch.remainder(heading.double() - total + math.pi, 2 * math.pi) - math.pi
    tol = 1e-8 if dtype == F64 else 1e-2
    assert diff.abs().max().item() < tol


def test_batched_shapes_and_per_element_equality():
    g = torch.Generator().manual_seed(0)
    E, A = 4, 5
    pos = torch.rand(E, A, 2, generator=g, dtype=F64) * 4
    heading = (torch.rand(E, A, generator=g, dtype=F64) - 0.5) * 2 * math.pi
    speed = (torch.rand(E, A, generator=g, dtype=F64) - 0.5) * 1.6
    steering = (torch.rand(E, A, generator=g, dtype=F64) - 0.5) * math.radians(70)
    new_pos, new_heading, vel = bicycle_step(pos, heading, speed, steering)
    assert new_pos.shape == (E, A, 2) and new_heading.shape == (E, A) and vel.shape == (E, A, 2)
    for e in range(E):
        for a in range(A):
            p, h, v = bicycle_step(pos[e, a], heading[e, a], speed[e, a], steering[e, a])
            torch.testing.assert_close(new_pos[e, a], p, atol=0, rtol=0)
            torch.testing.assert_close(new_heading[e, a], h, atol=0, rtol=0)
            torch.testing.assert_close(vel[e, a], v, atol=0, rtol=0)
    # Speed is conserved in magnitude: |velocity| = |v|.
    torch.testing.assert_close(vel.norm(dim=-1), speed.abs())
