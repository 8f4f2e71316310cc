"""Synthetic puck trajectories and mocap streams from the puck model (ground truth for tests and demos).

The true trajectory is the model integrated with a fine step (or another simulator's: pybullet, the test
bed, whose truth between samples is then theirs, not the model's); the mocap stream samples it at a nominal
rate with timestamp jitter, Gaussian noise, lost frames, repeated frames and one-frame glitches
(the imperfections of real OptiTrack recordings, issue #3).

Timestamp jitter is in the stamps: the cameras capture on their own clock, at the nominal frame times, and
the stamp the recording carries scatters about the capture (``jitter_std``), as software stamps do; the
lab's stamps scatter by about 0.2 ms (issue #13). A stream whose capture times themselves scatter, each
stamped exactly, is ``capture_jitter_std`` (0 by default).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.puck.model import PuckModel, wrap_angle


@dataclass(frozen=True)
class MocapImperfections:
    """Rates and sizes of the measurement imperfections (all may be zero)."""

    position_std: float = 1e-4       # [m] per axis, at rest
    position_std_per_speed: float = 0.0  # [s] std added in quadrature per m/s of puck speed
    angle_std: float = 1e-2          # [rad]
    jitter_std: float = 2e-4         # [s] timestamp jitter: the stamp's scatter about the capture time
    lost_rate: float = 0.0           # probability that a frame is missing
    repeat_rate: float = 0.0         # probability that a frame repeats the previous pose (frozen)
    glitch_rate: float = 0.0         # probability of a one-frame glitch
    glitch_size: float = 0.1         # [m] glitch displacement
    gap_rate: float = 0.0            # probability per frame that a longer dropout starts
    gap_max: float = 0.0             # [s] dropout length, uniform in (0, gap_max]
    heavy_tail_rate: float = 0.0     # probability that a frame's position noise is heavy_tail_scale times larger
    heavy_tail_scale: float = 1.0    # [-] (a contaminated Gaussian: seed 001's mixed-Gaussian noise)
    marker_offset_x: float = 0.0     # [m] where the rigid body's pivot sits off the disc's centre, in the
    marker_offset_y: float = 0.0     # puck's frame (it turns with the puck)
    capture_jitter_std: float = 0.0  # [s] the capture time's scatter about the nominal frame time

    @classmethod
    def from_params(cls, params: Mapping[str, Any], prefix: str = "mocap.") -> "MocapImperfections":
        """From parameters named ``<prefix><field>`` (e.g. ``mocap.lost_rate``)."""
        return cls(**{f.name: float(params[prefix + f.name]) for f in fields(cls)})


MOCAP_FIELDS = tuple(f.name for f in fields(MocapImperfections))  # parameter names: mocap.<field>
# their bounds: rates, sizes and stds are not negative; the pivot's offset is either way, within 5 cm
MOCAP_BOUNDS = {name: (-0.05, 0.05) if name.startswith("marker_offset") else (0.0, 10.0) for name in MOCAP_FIELDS}


@dataclass(frozen=True)
class ShotRanges:
    """Ranges of the random shots of a synthetic session (uniform draws)."""

    speed: tuple[float, float]       # [m/s]
    spin: tuple[float, float]        # [rad/s]
    duration: float                  # [s] recorded time per shot
    pause: float                     # [s] time without frames between shots (puck carried back)


def simulate_truth(model: PuckModel, state: np.ndarray, duration: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """True states every ``dt`` [s] for ``duration`` [s]: times (n,), states (n, 6)."""
    n = int(round(duration / dt)) + 1
    states = np.empty((n, 6))
    states[0] = state
    for i in range(1, n):
        states[i] = model.step(states[i - 1], dt, with_jacobian=False).state
    return np.arange(n) * dt, states


def true_state_at(model: PuckModel, times: np.ndarray, states: np.ndarray, t: float) -> np.ndarray:
    """True state at any time t [s] within the trajectory: the model stepped from the sample before t."""
    fine_dt = times[1] - times[0]
    index = min(int(np.clip(t, 0.0, times[-1]) / fine_dt), len(times) - 1)
    rest = t - times[index]
    return states[index] if rest <= 0.0 else model.step(states[index], rest, with_jacobian=False).state


def stepped_state_at(times: np.ndarray, states: np.ndarray, t: float) -> np.ndarray:
    """True state at any time t [s] within a trajectory from a simulator that is not the tracker's model
    (pybullet, the test bed), without that model: both integrate semi-implicitly, each step moving in a
    straight line at the velocity it ends with, so position and angle are interpolated linearly inside the
    step and velocity and spin are the step's own (its end values). Inside a step with a rim impact the
    line cuts the simulator's corner by at most half a step's travel (0.5 mm at 1 m/s and 1 kHz)."""
    index = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1))
    if t <= times[index] or index + 1 == len(times):
        return states[index].copy()
    before, after = states[index], states[index + 1]
    frac = (t - times[index]) / (times[index + 1] - times[index])
    return np.array([before[0] + frac * (after[0] - before[0]), before[1] + frac * (after[1] - before[1]),
                     after[2], after[3], wrap_angle(before[4] + frac * wrap_angle(after[4] - before[4])), after[5]])


StateAt = Callable[[np.ndarray, np.ndarray, float], np.ndarray]


def model_state_at(model: PuckModel) -> StateAt:
    """:func:`true_state_at` of ``model`` as a ``state_at(times, states, t)``."""
    return lambda times, states, t: true_state_at(model, times, states, t)


class MocapSampler:
    """Turns true poses into mocap frames with the imperfections of :class:`MocapImperfections`.

    One call per nominal frame time: a dropout swallows frames silently, a lost frame has no pose,
    a repeated frame re-sends the previous pose, a glitch displaces one frame by ``glitch_size``.
    Used by the synthetic sessions and by the table simulation's OptiTrack stand-in.
    """

    def __init__(self, noise: MocapImperfections, rng: np.random.Generator) -> None:
        self.noise, self.rng = noise, rng
        self.previous: np.ndarray | None = None
        self.gap_until = -math.inf

    def sample(self, t: float, pose_at: Callable[[float], Sequence[float]],
               t_max: float = math.inf) -> tuple[float, np.ndarray | None] | None:
        """Frame due at nominal time ``t`` [s]: None inside a dropout, else (stamp, (x, y, theta) or None).
        ``pose_at(captured)`` gives the true (x, y, theta) and speed [m/s] at the capture time (``t``, or
        scattered by ``capture_jitter_std``; :meth:`sample_captured` returns it too)."""
        frame = self.sample_captured(t, pose_at, t_max)
        return None if frame is None else frame[:2]

    def sample_captured(self, t: float, pose_at: Callable[[float], Sequence[float]],
                        t_max: float = math.inf) -> tuple[float, np.ndarray | None, float] | None:
        """:meth:`sample` with the capture time [s]: None, or (stamp, pose or None, captured)."""
        noise, rng = self.noise, self.rng
        if t < self.gap_until:
            return None
        if rng.random() < noise.gap_rate:
            self.gap_until = t + rng.uniform(0.0, noise.gap_max)
            return None
        # a stream stamped exactly with scattered captures (capture_jitter_std alone) draws as the same
        # stream with its scatter in the stamps (jitter_std alone), so the two differ in the poses only
        captured = t + (rng.normal(0.0, noise.capture_jitter_std) if noise.capture_jitter_std else 0.0)
        captured = float(np.clip(captured, 0.0, t_max))
        stamp = captured + (rng.normal(0.0, noise.jitter_std) if noise.jitter_std else 0.0)
        stamp = float(np.clip(stamp, 0.0, t_max))
        if rng.random() < noise.lost_rate:
            return stamp, None, captured
        x, y, theta, speed = pose_at(captured)
        std = math.hypot(noise.position_std, noise.position_std_per_speed * speed)
        if noise.heavy_tail_rate and rng.random() < noise.heavy_tail_rate:  # drawn only when on: same bags
            std *= noise.heavy_tail_scale
        if noise.marker_offset_x or noise.marker_offset_y:
            cos, sin = math.cos(theta), math.sin(theta)
            x += cos * noise.marker_offset_x - sin * noise.marker_offset_y
            y += sin * noise.marker_offset_x + cos * noise.marker_offset_y
        z = np.array([x + rng.normal(0.0, std), y + rng.normal(0.0, std),
                      wrap_angle(theta + rng.normal(0.0, noise.angle_std))])
        if self.previous is not None and rng.random() < noise.repeat_rate:
            z = self.previous.copy()
        elif rng.random() < noise.glitch_rate:
            direction = rng.uniform(0.0, 2.0 * np.pi)
            z[:2] += noise.glitch_size * np.array([np.cos(direction), np.sin(direction)])
        self.previous = z
        return stamp, z, captured


def mocap_stream(model: PuckModel, times: np.ndarray, states: np.ndarray, rate: float,
                 noise: MocapImperfections, rng: np.random.Generator,
                 state_at: StateAt | None = None) -> list[tuple[float, np.ndarray | None]]:
    """Sample a true trajectory as a mocap stream: list of (stamp [s], (x, y, theta) or None if lost).
    ``state_at(times, states, t)`` gives the truth between samples (default: the model, :func:`true_state_at`)."""
    return [(stamp, z) for stamp, z, _ in captured_stream(model, times, states, rate, noise, rng, state_at)]


def captured_stream(model: PuckModel, times: np.ndarray, states: np.ndarray, rate: float,
                    noise: MocapImperfections, rng: np.random.Generator,
                    state_at: StateAt | None = None) -> list[tuple[float, np.ndarray | None, float]]:
    """:func:`mocap_stream` with each frame's capture time: (stamp [s], pose or None, captured [s])."""
    sampler = MocapSampler(noise, rng)
    state_at = state_at or model_state_at(model)

    def pose_at(captured: float) -> Sequence[float]:
        x, y, vx, vy, theta, _ = state_at(times, states, captured)
        return x, y, theta, math.hypot(vx, vy)

    frames = (sampler.sample_captured(k / rate, pose_at, times[-1]) for k in range(int(times[-1] * rate)))
    return [f for f in frames if f is not None]


def random_shot(model: PuckModel, shots: ShotRanges, rng: np.random.Generator) -> np.ndarray:
    """A puck state anywhere on the table, moving in a random direction at a random speed and spin."""
    table = model.table
    margin = table.puck_radius
    heading = rng.uniform(-np.pi, np.pi)
    speed = rng.uniform(*shots.speed)
    return np.array([rng.uniform(-table.x_limit + margin, table.x_limit - margin),
                     rng.uniform(-table.y_limit + margin, table.y_limit - margin),
                     speed * np.cos(heading), speed * np.sin(heading),
                     rng.uniform(-np.pi, np.pi), rng.uniform(*shots.spin)])


@dataclass
class SyntheticFrame:
    stamp: float                     # [s] session time
    measurement: np.ndarray | None   # table frame (x, y, theta); None = lost
    truth: np.ndarray                # true state when the frame was captured
    captured: float | None = None    # [s] session time of the capture (None: the stamp)


Simulate = Callable[[np.ndarray, float], "tuple[np.ndarray, np.ndarray]"]


def synthetic_session(model: PuckModel, shots: ShotRanges, n_shots: int, rate: float,
                      noise: MocapImperfections, rng: np.random.Generator,
                      fine_dt: float, simulate: Simulate | None = None) -> list[SyntheticFrame]:
    """Consecutive random shots recorded like a mocap session (a bag generator for tests and tools).

    Each shot's truth comes from ``simulate(state, duration) -> (times, states)`` (default: the puck
    model integrated with ``fine_dt`` [s]; the table simulation or the test bed can stand in, and then the
    truth between their samples is theirs, :func:`stepped_state_at`, not the model's) and is sampled by
    :func:`mocap_stream`; a pause without frames separates shots. Shots that leave the table through
    a goal end there.
    """
    state_at = stepped_state_at if simulate is not None else model_state_at(model)
    if simulate is None:
        def simulate(state: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
            return simulate_truth(model, state, duration, fine_dt)
    session: list[SyntheticFrame] = []
    offset = 0.0
    for _ in range(n_shots):
        times, states = simulate(random_shot(model, shots, rng), shots.duration)
        for stamp, z, captured in captured_stream(model, times, states, rate, noise, rng, state_at):
            truth = state_at(times, states, captured)
            if not model.table.contains(truth[0], truth[1], model.table.puck_radius):
                break  # scored: the recording of this shot ends
            session.append(SyntheticFrame(offset + stamp, z, truth, offset + captured))
        offset += shots.duration + shots.pause
    return session
