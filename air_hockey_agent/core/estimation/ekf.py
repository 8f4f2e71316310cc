"""Extended Kalman filter for the puck (thesis sec. 3.2, 4.2) on irregular mocap frames.

* predict: the model (:mod:`.puck_model`) over the actual time since the last frame; a normal frame is
  one step of that length (process noise scaled by its length), a longer gap uses the fast predictor
  in model steps (:func:`.prediction.predict_fast`).
* update: measurement (x, y, theta), angle innovation wrapped to (-pi, pi] (eq. 3.7-3.11); the position
  noise grows with the speed (``measurement_noise_per_speed``, issue #13), and after a rim impact the
  velocity and spin get ``impact_noise`` of their size as extra uncertainty.
* lost frames: predict without update. Repeated timestamps and frozen positions (a mocap frame whose
  position equals the previous one within ``frozen_threshold``, thesis sec. 4.5.1) are not fused.
* outliers: position and angle are gated apart. A squared Mahalanobis distance of the position
  innovation above ``gate_threshold`` (2 dof) rejects the frame; after ``max_consecutive_rejections``
  rejected frames in a row the filter re-initialises from them (the puck was hit by something the model
  does not know, or the track was lost), instead of drifting forever. A good position whose angle
  fails ``angle_gate_threshold`` (1 dof) is fused without it. Frames beyond the table by more than
  ``outside_table_margin`` are dropped before gating.
* a hand (or a mallet) moving the puck: a restart from rejected frames that stopped the puck, or the
  second within ``hand.window``, starts the hand regime (:mod:`.hand_regime`), which follows the puck
  with a hand's accelerations as process noise instead of restarting every few frames, until the motion
  is the model's again.
* the robots' mallets (``mallet_contact.*``, :mod:`.mallet_contacts`): given their positions
  (:meth:`PuckEKF.observe_mallet`, from the robots' joint states), a mallet the estimate meets between two
  frames hits the puck there, seen or not (a puck smashed during a mocap dropout flies on in the estimate).
* (re)initialisation: a least-squares constant-velocity fit over the collected frames (the first
  ``ACQUISITION_FRAMES`` of a track whose fit agrees with the measurement noise, the rejected run after
  an event; seed 003's batch estimate), with the fit's covariance.
* what is learned online of the table (``rim_adaptation.*``, ``acceleration_adaptation.*``,
  :mod:`.table_learning`): after each frame handled without a restart the frame goes to the learning
  (a rejected one as a frame without a pose), which scales the configured rim law from the impacts it
  sees and estimates the table's acceleration from free flight; the model (and every prediction) then
  uses what was learned. It survives :meth:`PuckEKF.reset` (it is the table's, not the track's).
* the noise learned online: R from the poses themselves (``noise_adaptation``,
  :mod:`.noise_adaptation`) and the process noise by regime (flight, rest, rim impacts) from the gated
  frames' position NIS (``process_noise_adaptation``, :mod:`.process_noise_adaptation`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.estimation.hand_regime import HandRegime, HandSettings
from air_hockey_agent.core.estimation.mallet_contacts import (MalletContactSettings, MalletTracks, apply_contact,
                                                              first_contact)
from air_hockey_agent.core.estimation.marker_offset import centre_of
from air_hockey_agent.core.estimation.noise_adaptation import MarkerNoiseAdaptation
from air_hockey_agent.core.estimation.process_noise_adaptation import ProcessNoiseAdaptation
from air_hockey_agent.core.estimation.table_learning import TableLearning, learning_report
from air_hockey_agent.core.linalg3 import inverse_sym3
from air_hockey_agent.core.puck.prediction import Prediction, predict_fast, with_impact_noise
from air_hockey_agent.core.puck.model import PuckModel, PuckParams, wrap_angle
from air_hockey_agent.core.table import TableGeometry

MEASURED = (0, 1, 4)  # state indices of the measurement (x, y, theta)
POSITION = (0, 1)     # ... and of its position part (fused alone when the angle fails its gate)
_MEASURED_ROWS = np.array(MEASURED)
_MEASURED_BLOCK = np.ix_(MEASURED, MEASURED)  # index of the 3x3 measured block of P (built once: it is hot)

FLAG_PREDICTED = 1          # same values as air_hockey_msgs/PuckState.FLAG_*
FLAG_MEASUREMENT_USED = 2
FLAG_OUTLIER_REJECTED = 4
FLAG_REINITIALISED = 8

SINGLE_STEP_LIMIT = 1.5  # frames up to 1.5 model steps long are predicted as one step of their length
# A track starts from this many frames: the fewest whose constant-velocity fit (2 values per axis) leaves
# a residual to check, so a glitch or a hit still under way cannot set the first velocity unseen.
ACQUISITION_FRAMES = 3


@dataclass
class FilterSettings:
    """Noise and robustness settings; defaults and sources in ``config/tracker.yaml``."""

    dt: float                        # [s] model step
    q: np.ndarray                    # 6x6 process noise per model step
    r: np.ndarray                    # 3x3 measurement noise
    p0: np.ndarray                   # 6x6 covariance after (re)initialisation
    gate_threshold: float            # squared Mahalanobis distance
    max_consecutive_rejections: int
    outside_table_margin: float      # [m]
    max_prediction_gap: float        # [s]
    frozen_threshold: float = 1e-6   # [m] thesis sec. 4.5.1
    glitch_speed: float | None = None  # [m/s] evaluation only: a pose this far from both neighbours is no truth
    r_per_speed: float = 0.0         # [s] position noise std added (in quadrature) per m/s of puck speed
    angle_gate_threshold: float = math.inf  # squared angle innovation / its variance; beyond: position only
    impact_noise: float = 0.0        # [-] velocity/spin std after a rim impact, as a fraction of their size
    impact_contact_time: float = 0.0  # [s] position std after a rim impact, as the travel in this time
    ukf_alpha: float = 1.0           # [-] sigma-point spread (filter: ukf, mee_ukf; :mod:`.ukf`)
    ukf_beta: float = 2.0            # [-] prior-distribution term of the centre's covariance weight
    mee_kernel: float = 3.0          # [std] Gaussian kernel bandwidth of the MEE update (filter: mee_ukf)
    mee_fiducial: float = 0.5        # [-] weight of the fiducial (zero-error) point in the MEE cost
    mee_max_iterations: int = 10     # fixed-point iterations of the MEE update at most
    q_rest: np.ndarray | None = None  # 6x6 process noise per step of a puck slower than rest_speed (None: q)
    rest_speed: float = 0.0          # [m/s] regime boundary of q_rest (and of the evaluation's NIS by regime)
    imm_switch_probability: float = 0.002  # [-] per frame, of leaving a motion mode (filter: imm; :mod:`.imm`)
    imm_rim_impact_noise: float = 0.5     # [-] the rim mode's impact noise (the free mode's: impact_noise)
    imm_contact_speed: float = 2.0        # [m/s] std of the contact mode's velocity change in one frame
    imm_contact_spin: float = 10.0        # [rad/s] ... and of its spin change
    marker_offset: tuple[float, float] = (0.0, 0.0)  # [m] mocap pivot off the centre, puck frame (.marker_offset)
    hand: HandSettings = field(default_factory=HandSettings)  # a hand moving the puck (:class:`HandSettings`)
    mallet: MalletContactSettings = field(default_factory=MalletContactSettings)  # (:mod:`.mallet_contacts`)

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "FilterSettings":
        return cls(dt=1.0 / params["frequency"], q=np.diag(params["process_noise"]),
                   r=np.diag(params["measurement_noise"]), p0=np.diag(params["initial_covariance"]),
                   gate_threshold=params["gate_threshold"],
                   max_consecutive_rejections=params["max_consecutive_rejections"],
                   outside_table_margin=params["outside_table_margin"],
                   max_prediction_gap=params["max_prediction_gap"], glitch_speed=params["glitch_speed"],
                   r_per_speed=params["measurement_noise_per_speed"],
                   angle_gate_threshold=params["angle_gate_threshold"], impact_noise=params["impact_noise"],
                   impact_contact_time=params["impact_contact_time"],
                   ukf_alpha=params["ukf.alpha"], ukf_beta=params["ukf.beta"], mee_kernel=params["mee.kernel"],
                   mee_fiducial=params["mee.fiducial"], mee_max_iterations=params["mee.max_iterations"],
                   imm_switch_probability=params["imm.switch_probability"],
                   imm_rim_impact_noise=params["imm.rim_impact_noise"], imm_contact_speed=params["imm.contact_speed"],
                   imm_contact_spin=params["imm.contact_spin"], q_rest=np.diag(params["process_noise_rest"]),
                   rest_speed=params["regime_rest_speed"],
                   marker_offset=(float(params["marker_offset"][0]), float(params["marker_offset"][1])),
                   hand=HandSettings.from_params(params), mallet=MalletContactSettings.from_params(params))

    def process_noise(self, state: Sequence[float]) -> np.ndarray:
        """Q per model step for a step from ``state``: ``q_rest`` for a puck slower than ``rest_speed``
        (noise by regime, issue #13; the rim-impact regime adds ``impact_noise``), else ``q``."""
        if self.q_rest is not None and math.hypot(state[2], state[3]) < self.rest_speed:
            return self.q_rest
        return self.q

    def measurement_noise(self, speed: float) -> np.ndarray:
        """R [m^2, m^2, rad^2] for a puck moving at ``speed`` [m/s]: marker noise and timestamp jitter
        grow the position noise with the speed (issue #13: 0.15 mm at rest, 1.5 mm at 2-5 m/s)."""
        if self.r_per_speed == 0.0:
            return self.r
        r = self.r.copy()
        extra = (self.r_per_speed * speed) ** 2
        r[0, 0] += extra
        r[1, 1] += extra
        return r


@dataclass
class FilterStats:
    frames: int = 0
    lost_frames: int = 0
    outliers_rejected: int = 0   # poses on the table the gate rejected
    off_table: int = 0           # poses beyond the table by more than outside_table_margin (not the puck on it)
    reinitialisations: int = 0
    repeated_frames: int = 0
    hand_frames: int = 0         # frames handled in the hand regime (.hand_regime)
    hand_regimes: int = 0        # times the hand regime started
    mallet_contacts: int = 0     # contacts with a mallet the estimate met (.mallet_contacts)


@dataclass
class _Measurement:
    t: float
    z: np.ndarray


def check_covariance(matrix: np.ndarray, size: int, name: str) -> np.ndarray:
    """Return ``matrix`` as a float array if it is a finite symmetric positive definite size x size matrix."""
    matrix = np.asarray(matrix, float)
    if matrix.shape != (size, size):
        raise ValueError(f"{name} must be {size}x{size}, got shape {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise ValueError(f"{name} has non-finite entries")
    if not np.allclose(matrix, matrix.T, rtol=1e-9, atol=1e-15):
        raise ValueError(f"{name} is not symmetric")
    if np.linalg.eigvalsh(matrix).min() <= 0.0:
        raise ValueError(f"{name} is not positive definite")
    return matrix


@dataclass
class PuckEKF:
    """EKF state (mean ``x``, covariance ``P`` at ``stamp`` [s]) with its model and settings."""

    model: PuckModel
    settings: FilterSettings
    x: np.ndarray = field(default_factory=lambda: np.zeros(6))
    P: np.ndarray = field(default_factory=lambda: np.eye(6))
    stamp: float | None = None
    initialised: bool = False
    stats: FilterStats = field(default_factory=FilterStats)
    _pending: list = field(default_factory=list)      # measurements awaiting (re)initialisation
    _last_z: np.ndarray | None = None
    _angle_rejections: int = 0                          # good positions in a row fused without their angle
    _failed_acquisitions: int = 0                       # acquisition windows in a row whose fit disagreed
    # normalised innovation squared y^T S^-1 y of the last frame that reached the gate (fused or rejected),
    # None when the last frame did not (lost, frozen, initialising): the filter's consistency check
    last_nis: float | None = None
    learning: TableLearning | None = None              # what is learned online of the table (None: nothing)
    noise_learning: MarkerNoiseAdaptation | None = None  # the mocap's noise learned online (None: R as set)
    process_noise_learning: ProcessNoiseAdaptation | None = None  # Q by regime learned online (None: as set)
    _frames_since_impact: int = 1 << 30                # gated frames since the model last put a rim impact
    hand: HandRegime | None = None                     # a hand moving the puck (:mod:`.hand_regime`; None: built
                                                       # from settings.hand after __init__)
    mallets: MalletTracks | None = None                # the robots' mallets (:mod:`.mallet_contacts`; None: not
                                                       # used; built after __init__ when settings.mallet.enabled)
    mallet_met: str | None = None                      # the mallet the estimate met in the last frame or coast
    _frames_since_mallet: int = 1 << 30                # gated frames since the estimate last met a mallet
    _coasted_from: float | None = None                 # [s] the stamp before coasting since the last frame
    _unseen_contact: bool = False                      # a mallet met while coasting since the last frame

    def __post_init__(self) -> None:
        """The hand regime from the settings; a subclass with state of its own sets it up too (the generated
        ``__init__`` calls this)."""
        if self.hand is None:
            self.hand = HandRegime(self.settings.hand)
        if self.mallets is None and self.settings.mallet.enabled:
            self.mallets = MalletTracks(self.settings.mallet.max_age)

    @property
    def in_hand(self) -> bool:
        """Whether the hand regime (:mod:`.hand_regime`) holds."""
        return self.hand.active

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "PuckEKF":
        """The filter a tracker parameter set (``tracker_params``) selects with ``filter`` (ekf; ukf,
        mee_ukf: :mod:`.ukf`; imm: :mod:`.imm`), on its table, model and noise settings."""
        from air_hockey_agent.core.estimation.imm import PuckIMM
        from air_hockey_agent.core.estimation.ukf import PuckMEEUKF, PuckUKF
        kind = {"ekf": PuckEKF, "ukf": PuckUKF, "mee_ukf": PuckMEEUKF, "imm": PuckIMM}[params.get("filter", "ekf")]
        model = PuckModel(TableGeometry.from_params(params), PuckParams.from_params(params))
        ekf = kind(model, FilterSettings.from_params(params))
        ekf.learning = TableLearning.from_params(model.params, model.table, params)
        ekf.noise_learning = MarkerNoiseAdaptation.from_params(params)
        ekf.process_noise_learning = ProcessNoiseAdaptation.from_params(params)
        return ekf

    @property
    def learned(self) -> tuple[int, int]:
        """(rim impacts, free-flight windows) the model has learned from online so far; (0, 0) without
        learning: what changes whenever the model's physics does, short of ``set_model_params``."""
        return self.learning.counts if self.learning is not None else (0, 0)

    def learning_report(self) -> dict:
        """What was learned online: the table's (:func:`~.table_learning.learning_report`, its keys None when
        nothing is), ``"marker_noise"`` (:meth:`MarkerNoiseAdaptation.report`) and ``"process_noise"``
        (:meth:`ProcessNoiseAdaptation.report`), each None when not learned."""
        report = learning_report(self.learning)
        report["marker_noise"] = None if self.noise_learning is None else self.noise_learning.report()
        report["process_noise"] = (None if self.process_noise_learning is None
                                   else self.process_noise_learning.report())
        return report

    def set_model_params(self, params: PuckParams) -> None:
        """Use ``params`` (validated: ValueError, filter unchanged); what was learned online restarts from them."""
        self.model = self.model.with_params(params)
        if self.learning is not None:
            self.learning = self.learning.restarted(params)

    # --- state management -------------------------------------------------------------------------
    def reset(self, state: Sequence[float] | None = None, stamp: float | None = None) -> None:
        """Forget everything; with ``state``, restart there with covariance P0.

        ``state`` holds at ``stamp`` [s]; without a stamp it holds at the next frame's time (a state set
        by hand, e.g. through the node's ``reset`` service with a zero header stamp).
        """
        self._pending.clear()
        self._failed_acquisitions = 0
        self._last_z = None
        self.hand = HandRegime(self.settings.hand)
        if self.learning is not None:
            self.learning.forget()
        if state is None:
            self.initialised, self.stamp = False, None
            return
        self.x, self.P = np.asarray(state, float).copy(), self.settings.p0.copy()
        self.x[4] = wrap_angle(self.x[4])
        self.initialised, self.stamp = True, stamp

    def _initialise_from_pending(self) -> None:
        """Restart from the collected measurements (all since the event: the frames rejected in a row, or
        a new track's first consistent ones) by a least-squares constant-velocity fit (seed 003's batch estimate
        over the frames since the event, short enough for the model's deceleration not to matter), with
        the fit's own covariance; then forget them."""
        last = self._pending[-1]
        _, _, coef, gram_inv = self._pending_line_fit()
        speed = math.hypot(coef[1, 0], coef[1, 1])
        r = np.diag(self.settings.measurement_noise(speed))
        state = [coef[0, 0], coef[0, 1], coef[1, 0], coef[1, 1], wrap_angle(coef[0, 2]), coef[1, 2]]
        self.reset(state, last.t)
        for value, rate, noise in ((0, 2, r[0]), (1, 3, r[1]), (4, 5, r[2])):
            block = noise * gram_inv
            self.P[value, value], self.P[rate, rate] = block[0, 0], block[1, 1]
            self.P[value, rate] = self.P[rate, value] = block[0, 1]
        self._last_z = last.z
        self.stats.reinitialisations += 1

    def _pending_line_fit(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The collected frames' least-squares constant-velocity fit, times counted from the last frame: (their
        (x, y, theta), angles unwrapped about the last one; the design [1, t]; the coefficients, rows value at
        the last frame and rate; (A^T A)^-1, the fit's covariance per unit noise)."""
        last = self._pending[-1]
        t = np.array([m.t for m in self._pending]) - last.t
        z = np.array([m.z for m in self._pending])
        z[:, 2] = last.z[2] + np.array([wrap_angle(a - last.z[2]) for a in z[:, 2]])
        design = np.column_stack([np.ones_like(t), t])
        gram_inv = np.linalg.inv(design.T @ design)
        return z, design, gram_inv @ design.T @ z, gram_inv

    # --- filter steps -----------------------------------------------------------------------------
    def predict_to(self, t: float) -> None:
        """Propagate mean and covariance to time ``t`` [s] (t >= stamp)."""
        dt = t - self.stamp
        if dt <= 0.0:
            return
        if dt <= SINGLE_STEP_LIMIT * self.settings.dt:
            q = self._step_noise(self.x, dt)
            res = self.model.step(self.x, dt)
            self.x = res.state
            p = res.jacobian @ self.P @ res.jacobian.T + q
            self.P = self._with_impact_noise(p, self.x, res.impacts)
        else:
            pred = predict_fast(self.model, self.x, self.P, dt, self.settings.dt, self.settings.q,
                                impact_noise=self.settings.impact_noise,
                                impact_contact_time=self.settings.impact_contact_time)
            self.x, self.P = pred.state, pred.covariance
            if self.in_hand:
                self.P = self.P + self.settings.hand.noise(dt, self.settings.dt)
            self._impacts_met(pred.impacts)
        self.stamp = t

    def _step_noise(self, state: np.ndarray, dt: float) -> np.ndarray:
        """Q of a step of ``dt`` [s] from ``state``: the regime the step starts in (``process_noise``),
        plus the hand's in the hand regime (:mod:`.hand_regime`)."""
        q = self.settings.process_noise(state) * (dt / self.settings.dt)
        return q + self.settings.hand.noise(dt, self.settings.dt) if self.in_hand else q

    def _with_impact_noise(self, p: np.ndarray, x: np.ndarray, impacts: list) -> np.ndarray:
        """``p`` with the impact noise of a step that met ``impacts`` (:func:`with_impact_noise`), counted
        for the impact regime."""
        self._impacts_met(impacts)
        return with_impact_noise(p, x, impacts, self.settings.impact_noise, self.settings.impact_contact_time)

    def _impacts_met(self, impacts: list) -> None:
        """A step the model put ``impacts`` in: the next gated frames are the impact regime's."""
        if impacts:
            self._frames_since_impact = 0

    def residual(self, z: np.ndarray, state: np.ndarray | None = None) -> np.ndarray:
        """Measurement minus the measured part of the current state (or of ``state``), ``z - h(x)``, angle
        wrapped."""
        y = np.asarray(z, float) - (self.x if state is None else state)[_MEASURED_ROWS]
        y[2] = wrap_angle(y[2])
        return y

    def innovation(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Innovation y (angle wrapped), its covariance S and squared Mahalanobis distance."""
        y, s = self._innovation_and_covariance(z)
        s_inv = inverse_sym3(s)
        return y, s_inv, float(y @ s_inv @ y)

    def _innovation_and_covariance(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Innovation y (angle wrapped) and its covariance S = P_zz + R(speed)."""
        return self.residual(z), self.P[_MEASURED_BLOCK] + self.settings.measurement_noise(
            math.hypot(self.x[2], self.x[3]))

    def update(self, z: np.ndarray) -> float:
        """Fuse measurement z = (x, y, theta) unconditionally (eq. 3.7-3.11); returns its distance."""
        y, s_inv, d2 = self.innovation(z)
        self._apply_update(y, s_inv)
        return d2

    def _apply_update(self, y: np.ndarray, s_inv: np.ndarray, rows: Sequence[int] = MEASURED) -> None:
        """Kalman gain, mean and covariance update from innovation y and S^-1 (eq. 3.9-3.11) of the
        measured state components ``rows`` (all three, or the position alone)."""
        p_ht = self.P[:, rows]
        gain = p_ht @ s_inv
        self.x = self.x + gain @ y
        self.x[4] = wrap_angle(self.x[4])
        p = self.P - gain @ p_ht.T
        self.P = 0.5 * (p + p.T)

    def plausible(self, z: Sequence[float]) -> bool:
        """A measurement (x, y, theta) can be the puck: finite and on the table within
        ``outside_table_margin`` (farther out it is a glitch, dropped before the gate)."""
        values = z.tolist() if isinstance(z, np.ndarray) else [float(v) for v in z]  # scalars: no numpy calls
        return all(map(math.isfinite, values)) and self.model.table.contains(values[0], values[1],
                                                                             self.settings.outside_table_margin)

    @property
    def marker_offset(self) -> tuple[float, float]:
        """[m] The mocap pivot's offset from the disc's centre (puck frame) measured positions are taken
        back by: learned online, or ``marker_offset`` as configured."""
        return self.settings.marker_offset if self.learning is None else self.learning.marker_offset

    def process(self, t: float, z: Sequence[float] | None) -> int:
        """Handle one mocap frame at time ``t`` [s]: measurement ``z`` (x, y, theta) or None (lost).

        Returns ``FLAG_*`` bits describing what was done. A measured position is the mocap pivot's: it is
        taken back to the disc's centre by the marker offset (configured or learned) first.
        """
        if self.noise_learning is not None:
            self._learn_noise(t, z)
        offset = self.marker_offset
        if z is not None and (offset[0] or offset[1]) and math.isfinite(z[2]):  # else plausible() drops it
            z = centre_of(np.asarray(z, float), offset)
        if self.learning is None:
            return self._process(t, z)
        x, p, stamp, initialised = self.x, self.P, self.stamp, self.initialised  # steps replace, not change, x and P
        flags = self._process(t, z)
        if not (initialised and self.initialised and stamp is not None) or flags & FLAG_REINITIALISED \
                or self.mallet_met is not None:  # the learning's windows hold the table's motion alone
            self.learning.forget()
            return flags
        learned = self.learning.after_frame(self.model, t, z if flags & FLAG_MEASUREMENT_USED else None, x, p, stamp)
        if learned is not None:
            try:
                self.model = self.model.with_params(learned)
            except ValueError:  # a law the model refuses (the learning clamps its values) is not taken
                pass
        return flags

    def _learn_noise(self, t: float, z: Sequence[float] | None) -> None:
        """Give the pose (or its absence) to the noise learning; take R from it when it refits
        (``measurement_noise`` at rest and its angle term, ``measurement_noise_per_speed``)."""
        usable = z is not None and self.plausible(z)
        if self.noise_learning.observe(t, z if usable else None):
            learned = self.noise_learning
            r = np.diag([learned.a, learned.a, learned.angle])
            self.settings = replace(self.settings, r=r, r_per_speed=math.sqrt(learned.b))

    def _process(self, t: float, z: Sequence[float] | None) -> int:
        self.stats.frames += 1
        self.last_nis = None
        self.mallet_met = None
        last, self._coasted_from, self._unseen_contact = self._coasted_from, None, False
        flags = 0
        if z is not None:
            z = np.asarray(z, float)
            if not self.plausible(z):
                self.stats.off_table += 1
                z, flags = None, FLAG_OUTLIER_REJECTED
        if not self.initialised:
            return flags | self._collect_for_initialisation(t, z)
        if self.stamp is None:
            self.stamp = t  # a state set without a time holds at the first frame after it
        elif t < self.stamp - self.settings.max_prediction_gap:  # time jumped back (replay loop, sim restart)
            self.reset()
            return flags | self._collect_for_initialisation(t, z)
        elif t <= self.stamp:
            self.stats.repeated_frames += 1
            return flags
        if t - (self.stamp if last is None else last) > self.settings.max_prediction_gap:
            self.reset()
            return flags | self._collect_for_initialisation(t, z)
        if self.mallets is not None:
            self._meet_mallets(t)
        self.predict_to(t)
        if self.in_hand:
            self.stats.hand_frames += 1
        if z is None or self._is_frozen(z):
            self.stats.lost_frames += 1
            return flags | FLAG_PREDICTED
        return flags | self._gate_and_update(t, z)

    def observe_mallet(self, name: str, t: float, position: Sequence[float],
                       velocity: Sequence[float] | None = None) -> None:
        """Mallet ``name``'s centre (x, y) [m, table frame] at ``t`` [s] and its velocity [m/s] if known
        (:class:`.MalletTracks`); ignored unless ``mallet_contact.enabled``."""
        if self.mallets is not None:
            self.mallets.observe(name, t, position, velocity)

    def coast(self, t: float) -> bool:
        """No frame has come for ``mallet_contact.coast_after`` [s] or more before ``t`` [s] (a mocap dropout):
        predict to ``t`` meeting the mallets (:meth:`_meet_mallets`). Returns whether the estimate holds a
        mallet contact since the last frame (then it says more than the last frame's prediction, and is
        worth publishing). Not a frame: no statistics, no learning (a contact ends the learning's windows);
        ``max_prediction_gap`` still counts from the last frame, and a frame stamped before the coasted
        stamp comes too late (dropped as repeated). Only with ``mallet_contact.enabled``."""
        if self.mallets is None or not self.initialised or self.stamp is None or t <= self.stamp:
            return False
        since = t - (self.stamp if self._coasted_from is None else self._coasted_from)
        if since < self.settings.mallet.coast_after or since > self.settings.max_prediction_gap:
            return False  # a frame may still come; or the next frame restarts the track
        if self._coasted_from is None:
            self._coasted_from = self.stamp
        self.mallet_met = None
        self._meet_mallets(t)
        self.predict_to(t)
        if self.mallet_met is not None:
            self._unseen_contact = True
            if self.learning is not None:
                self.learning.forget()
        return self._unseen_contact

    def _meet_mallets(self, t: float) -> None:
        """Before predicting to ``t`` [s]: the first mallet the estimate meets on the way (each in a straight
        line from ``stamp``), if any, hits the puck there (:func:`.apply_contact`); one contact a frame."""
        horizon, reach = t - self.stamp, self.model.table.puck_radius + self.settings.mallet.radius
        met = None
        for name, position, velocity in self.mallets.at(self.stamp):
            s = first_contact(self.x[:2], self.x[2:4], position, velocity, reach, horizon)
            if s is not None and (met is None or s < met[0]):
                met = (s, name, position + velocity * s, velocity)
        if met is None:
            return
        s, name, position, velocity = met
        self.predict_to(self.stamp + s)
        self.x, self.P = apply_contact(self.x, self.P, position, velocity, self.settings.mallet,
                                       self.model.table.puck_radius)
        self._state_replaced()
        self.mallet_met, self._frames_since_mallet = name, 0
        self.stats.mallet_contacts += 1

    def _state_replaced(self) -> None:
        """The mean and covariance were set anew (a mallet contact): a filter with state of its own follows."""

    def _is_frozen(self, z: np.ndarray) -> bool:
        frozen = self._last_z is not None and math.hypot(*(z[:2] - self._last_z[:2])) < self.settings.frozen_threshold
        self._last_z = z
        return frozen

    def _gate_and_update(self, t: float, z: np.ndarray) -> int:
        """Position and angle are gated apart: a position beyond ``gate_threshold`` (2 dof) rejects the
        frame; a good position with an angle beyond ``angle_gate_threshold`` (1 dof) is fused without
        its angle, and after ``max_consecutive_rejections`` such angles in a row the angle and spin
        restart from the measurement (the spin model, not the marker, was wrong)."""
        y, s = self._innovation_and_covariance(z)
        s_inv = inverse_sym3(s)
        self.last_nis = float(y @ s_inv @ y)
        (sxx, sxy, _), (_, syy, _), (_, _, saa) = s.tolist()
        yx, yy, ya = y.tolist()
        position_d2 = (syy * yx * yx - 2.0 * sxy * yx * yy + sxx * yy * yy) / (sxx * syy - sxy * sxy)
        if self.process_noise_learning is not None and not self.in_hand:
            self._learn_process_noise(position_d2)
        if position_d2 <= self.settings.gate_threshold:
            self._pending.clear()
            velocity = (self.x[2], self.x[3])
            if ya * ya <= self.settings.angle_gate_threshold * saa:
                self._angle_rejections = 0
                self._apply_update(y, s_inv)
            else:
                self._update_position_only(y[:2], s[:2, :2], z[2])
            if self.in_hand:
                self.hand.watch(t, self.x[2] - velocity[0], self.x[3] - velocity[1])
            return FLAG_MEASUREMENT_USED
        self.stats.outliers_rejected += 1
        self._pending.append(_Measurement(t, z))
        if len(self._pending) >= self.settings.max_consecutive_rejections:
            self._restart_from_rejections(t)
            return FLAG_OUTLIER_REJECTED | FLAG_REINITIALISED | FLAG_MEASUREMENT_USED
        return FLAG_OUTLIER_REJECTED | FLAG_PREDICTED

    def _restart_from_rejections(self, t: float) -> None:
        """Restart at ``t`` [s] from the rejected run (:meth:`_initialise_from_pending`) and tell the hand
        regime what the restart kept of the predicted speed (:meth:`.HandRegime.after_restart`: a stop or a
        restart soon after another starts it, a hit ends it)."""
        predicted, steady, regime = math.hypot(self.x[2], self.x[3]), self._pending_consistent(), self.hand
        self._initialise_from_pending()
        self.hand = regime  # the restart's reset begins a new track; the regime goes on across it
        if self.hand.after_restart(t, predicted, math.hypot(self.x[2], self.x[3]), steady):
            self.stats.hand_regimes += 1

    def _learn_process_noise(self, position_d2: float) -> None:
        """Give a gated frame's position distance to the process noise learning
        (:mod:`.process_noise_adaptation`) by its regime: *impact* for the ``impact_frames`` after a model
        impact, *rest* below ``rest_speed``, *flight* clear of the rims (else none); take the noise from it
        when a block completes."""
        learning = self.process_noise_learning
        since, self._frames_since_impact = self._frames_since_impact, self._frames_since_impact + 1
        after_mallet, self._frames_since_mallet = self._frames_since_mallet, self._frames_since_mallet + 1
        if after_mallet < learning.settings.impact_frames:
            return  # a mallet contact's frames are none of the table's regimes
        x, y, vx, vy = self.x[:4].tolist()
        if since < learning.settings.impact_frames:
            regime = "impact"
        elif math.hypot(vx, vy) < self.settings.rest_speed:
            regime = "rest"
        elif self.model.table.clear_of_rims(x, y, vx, vy, learning.settings.clear_of_rims):
            regime = "flight"
        else:
            return
        if learning.observe(regime, position_d2):
            noise, contact = learning.impact()
            self.settings = replace(self.settings, q=learning.q("flight"), q_rest=learning.q("rest"),
                                    impact_noise=noise, impact_contact_time=contact)

    def _update_position_only(self, y: np.ndarray, s: np.ndarray, angle: float) -> None:
        """Fuse the position innovation ``y`` (covariance ``s``) alone; restart angle and spin from the
        measured ``angle`` after too many rejected angles in a row."""
        self._apply_update(y, np.linalg.inv(s), POSITION)
        self._angle_rejections += 1
        if self._angle_rejections >= self.settings.max_consecutive_rejections:
            self._angle_rejections = 0
            self._restart_angle(angle)

    def _restart_angle(self, angle: float) -> None:
        """Angle from the measured ``angle`` [rad], spin unknown, uncorrelated with the rest."""
        self.x[4], self.x[5] = wrap_angle(angle), 0.0
        self.P[4:6, :] = 0.0
        self.P[:, 4:6] = 0.0
        self.P[4, 4], self.P[5, 5] = self.settings.r[2, 2], self.settings.p0[5, 5]

    def _collect_for_initialisation(self, t: float, z: np.ndarray | None) -> int:
        """Start a track from the last ``ACQUISITION_FRAMES`` frames once their constant-velocity fit agrees
        with the measurement noise (:meth:`_pending_consistent`); a window that does not loses its oldest
        frame. A single glitch spoils every window holding it; more windows than that failing in a row
        mean the frames disagree for another reason (noise larger than ``measurement_noise`` says, a
        push going on), and the track starts anyway rather than never."""
        if z is None:
            return 0
        if self._pending and not 0.0 < t - self._pending[-1].t <= self.settings.max_prediction_gap:
            self._pending.clear()
            self._failed_acquisitions = 0
        self._pending.append(_Measurement(t, z))
        if len(self._pending) < ACQUISITION_FRAMES:
            return 0
        del self._pending[:-ACQUISITION_FRAMES]
        if not self._pending_consistent() and self._failed_acquisitions < ACQUISITION_FRAMES:
            self._failed_acquisitions += 1
            del self._pending[0]
            return 0
        self._failed_acquisitions = 0
        self._initialise_from_pending()
        return FLAG_REINITIALISED | FLAG_MEASUREMENT_USED

    def _pending_consistent(self) -> bool:
        """Whether the collected frames' positions fit a constant velocity within the measurement noise:
        the chi-square of the least-squares fit's residuals (2 n - 4 dof for n frames; 2 for the
        acquisition's 3, as the position gate) within ``gate_threshold``. Over a few frames the model's
        deceleration is far below the marker noise (0.4 m/s^2 moves 0.06 mm in 17 ms)."""
        z, design, coef, _ = self._pending_line_fit()
        residual = z[:, :2] - design @ coef[:, :2]
        r = self.settings.measurement_noise(math.hypot(coef[1, 0], coef[1, 1]))
        chi2 = float(residual[:, 0] @ residual[:, 0] / r[0, 0] + residual[:, 1] @ residual[:, 1] / r[1, 1])
        return chi2 <= self.settings.gate_threshold

    # --- prediction -------------------------------------------------------------------------------
    def predict(self, horizon: float, lines: Sequence[float] = (), sample_every: int = 0) -> Prediction:
        """Prediction from the current estimate over ``horizon`` [s] (filter state unchanged)."""
        return predict_fast(self.model, self.x, self.P, horizon, self.settings.dt, self.settings.q,
                            lines=lines, sample_every=sample_every, impact_noise=self.settings.impact_noise,
                            impact_contact_time=self.settings.impact_contact_time)

    def predict_from(self, model: PuckModel, x: np.ndarray, p: np.ndarray | None, horizon: float) -> Prediction:
        """Prediction ``horizon`` [s] ahead of a recorded state ``x`` (covariance ``p`` or None) with the model
        the filter had there (its physics as learned by then): the evaluation's (:mod:`.evaluation`; the
        configured process noise, no impact noise)."""
        return predict_fast(model, x, p, horizon, self.settings.dt, self.settings.q)
