"""What the simulation emits and when (ROS-free): physics steps, the OptiTrack stand-in, clock and joint states.

:class:`SimRunner` advances the :class:`~air_hockey_agent.sim.world.TableWorld` one physics step at a
time and reports which outputs fall due at that simulated time; the ``table_sim`` node only turns
them into messages. Rates are in simulated time, so the output does not depend on the real-time factor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from air_hockey_agent.core.frames import table_to_mocap
from air_hockey_agent.core.estimation.synthetic import MocapImperfections, MocapSampler
from air_hockey_agent.sim.contacts import TOUCHED_FLAGS
from air_hockey_agent.sim.world import TableWorld


class Every:
    """Fires at multiples of ``1/rate`` seconds of simulated time (at the first step at or after each)."""

    def __init__(self, rate: float) -> None:
        self.period = 1.0 / rate
        self.count = 0

    def due(self, t: float) -> float | None:
        """The nominal time of a tick that fell due by ``t``, or None (at most one per call)."""
        nominal = self.count * self.period
        if t + 1e-12 < nominal:
            return None
        self.count = math.floor(t / self.period + 1e-9) + 1
        return nominal


@dataclass
class StepOutput:
    """Outputs due after one physics step."""

    time: float                                   # [s] simulated time after the step
    clock: bool = False
    joint_states: bool = False
    true_state: np.ndarray | None = None          # with every mocap tick, lost frames included
    mocap: tuple | None = None                    # (stamp [s], (x, y, z, yaw) in the mocap frame)
    contacts: list = field(default_factory=list)  # mallet-puck contacts that ended at this step
    in_contact: tuple[str, ...] = ()              # with the true state: robots whose mallet is in a contact now

    @property
    def truth_flags(self) -> int:
        """The true state's air_hockey_msgs/PuckState flags: which mallets are in contact with the puck."""
        return sum(TOUCHED_FLAGS[robot] for robot in self.in_contact)


class SimRunner:
    """Steps the world and schedules clock, joint-state and mocap outputs."""

    def __init__(self, world: TableWorld, mocap_rate: float, noise: MocapImperfections, rng: np.random.Generator,
                 clock_rate: float, joint_state_rate: float, mocap_table_pose: Sequence[float]) -> None:
        self.world = world
        self.sampler = MocapSampler(noise, rng)
        self.table_pose = tuple(mocap_table_pose)
        self._clock, self._joints, self._mocap = Every(clock_rate), Every(joint_state_rate), Every(mocap_rate)

    def step(self) -> StepOutput:
        self.world.step()
        t = self.world.time
        out = StepOutput(t, clock=self._clock.due(t) is not None, joint_states=self._joints.due(t) is not None,
                         contacts=self.world.take_contacts())
        if self._mocap.due(t) is not None:  # the frame is taken now; its stamp carries the jitter
            truth = self.world.puck_state()
            out.true_state, out.in_contact = truth, self.world.in_contact()
            pose = (truth[0], truth[1], truth[4], math.hypot(truth[2], truth[3]))
            frame = self.sampler.sample(t, lambda _stamp: pose)
            if frame is not None and frame[1] is not None:
                stamp, (x, y, yaw) = frame
                mx, my, myaw = table_to_mocap(x, y, yaw, self.table_pose)
                out.mocap = (stamp, (mx, my, self.table_pose[2] + self.world.settings.puck_height / 2, myaw))
        return out
