# SPDX-License-Identifier: Apache-2.0
"""Per-finger sensor samples and their two-finger combination (control_and_estimation §1).

Per finger, in the raw sensor frames ``ft_sensor_k`` / ``vel_sensor_k`` (bias removed):
``f_n = |Fz|``, ``f_t = ‖(Fx, Fy)‖``, ``τ = Tz``, ``v = ‖(vx, vy)‖``, ``ω``.

Two-finger combination (§1.2): each finger's ``(Fx, Fy, Tz)`` and ``(vx, vy, ω)`` is rotated into
``gripper_middle`` with `slip_cell_common.core.frames.planar_to_middle` (finger 2's z flips);
then, with primes for middle-frame values,

* signed means ``v̄ = (v1' + v2')/2`` (xy), ``ω̄ = (ω1' + ω2')/2``, ``F̄ = (F1' + F2')/2``,
  ``τ̄ = (τ1' + τ2')/2`` — used for direction-aware progress (§4.2);
* the reference's magnitude-of-mean form ``vx = |vx1' + vx2'|/2`` etc. — its norms equal the
  norms of the signed means, so ``ft = ‖(F̄x, F̄y)‖``, ``D = ‖(F̄x, F̄y, τ̄/r)‖`` and
  ``v_s = ‖(v̄x, v̄y, r·ω̄)‖`` are computed from the signed means directly.

The reference's ``f_n`` (|mean of the middle-frame Fz|) is the *net* axial force, ≈ 0 in a
squeeze; we expose the grasp force ``−(Fz1 + Fz2)/2`` and the mean ``|Fz|`` instead (both only
logged by the controllers, §4.8).

Time: every sample carries its acquisition stamp [s]; freshness is judged against the
evaluation time ``t`` passed in by the caller (node clock or replay clock), never a wall clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from slip_cell_common.core.frames import FrameParams, planar_to_middle

INF = float('inf')


@dataclass(frozen=True, slots=True)
class WrenchSample:
    """Bias-removed wrench of one finger in ``ft_sensor_k``.

    Attributes:
        fx: Force x [N].
        fy: Force y [N].
        fz: Force z [N] (squeezing is negative).
        tz: Torque about z [N·m].
        stamp: Acquisition time [s].
        tx: Torque about x [N·m] (NaN when the source gives only the planar part).
        ty: Torque about y [N·m] (NaN likewise).
    """

    fx: float
    fy: float
    fz: float
    tz: float
    stamp: float
    tx: float = math.nan
    ty: float = math.nan

    @property
    def normal_force(self) -> float:
        """``f_n = |Fz|`` [N]."""
        return abs(self.fz)

    @property
    def tangential_force(self) -> float:
        """``f_t = ‖(Fx, Fy)‖`` [N]."""
        return math.hypot(self.fx, self.fy)

    def finite(self) -> bool:
        """The planar components and the stamp are finite numbers."""
        return all(math.isfinite(x) for x in (self.fx, self.fy, self.fz, self.tz, self.stamp))

    def centre_of_pressure(self, pad_offset: float) -> tuple[float, float] | None:
        """Centre of pressure ``(c_x, c_y)`` on the pad [m, ``ft_sensor_k``], or None.

        The contact force acts at ``(c_x, c_y, d)``, ``d`` = ``pad_offset`` (sensor origin to
        pad surface), so ``Tx = c_y·Fz − d·Fy`` and ``Ty = d·Fx − c_x·Fz``. None without
        ``Tx``/``Ty`` or without normal force.
        """
        if not (math.isfinite(self.tx) and math.isfinite(self.ty)) or self.fz == 0.0:
            return None
        return ((pad_offset * self.fx - self.ty) / self.fz,
                (self.tx + pad_offset * self.fy) / self.fz)

    def torque_about_cop(self, pad_offset: float) -> float:
        """Torque about the pad normal through the centre of pressure [N·m].

        ``τ_cop = Tz − (c_x·Fy − c_y·Fx)``; ``Tz`` itself when the centre is unknown.
        """
        c = self.centre_of_pressure(pad_offset)
        if c is None:
            return self.tz
        return self.tz - (c[0] * self.fy - c[1] * self.fx)


@dataclass(frozen=True, slots=True)
class TwistSample:
    """Slip twist of one finger in ``vel_sensor_k`` (object relative to pad).

    Attributes:
        vx: Sliding velocity x [m/s].
        vy: Sliding velocity y [m/s].
        omega: Rotation rate about z [rad/s].
        stamp: Acquisition time [s].
        valid: False when the sensor marks the sample unusable (e.g. ω invalid in single-chip
            mode); an invalid sample counts as stale.
    """

    vx: float
    vy: float
    omega: float
    stamp: float
    valid: bool = True

    @property
    def speed(self) -> float:
        """``v = ‖(vx, vy)‖`` [m/s]."""
        return math.hypot(self.vx, self.vy)

    def usable(self) -> bool:
        """Marked valid and all components finite."""
        return self.valid and all(
            math.isfinite(x) for x in (self.vx, self.vy, self.omega, self.stamp))


#: Longest sample interval a finger's travel integrates across [s]; a longer gap (stream
#: restarted, sensor unplugged) is not bridged with the new sample's velocity.
MAX_TRAVEL_SPAN = 0.1


@dataclass(frozen=True, slots=True)
class Travel:
    """Slip displacement of one finger, integrated over its own sample stamps (``vel_sensor_k``).

    Each sample's velocity is the sensor's mean over the interval since its previous sample
    (the chips report displacement per frame), so ``Σ v·Δstamp`` is the displacement whatever
    rate a consumer samples the stream at: a control step that sees only every third sample
    (executor backlog, DDS burst) still gets the full progress from the travel difference.

    Attributes:
        x: Integrated slip along x [m].
        y: Integrated slip along y [m].
        theta: Integrated rotation about z [rad].
        stamp: Stamp of the last sample taken in [s] (``None`` before the first).
    """

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    stamp: float | None = None

    def advanced(self, sample: TwistSample) -> Travel:
        """Travel after ``sample``: integrated over ``0 < Δstamp ≤ MAX_TRAVEL_SPAN``.

        A repeated stamp changes nothing; an older stamp (clock jumped back), a longer gap or
        an unusable sample (NaN, marked invalid) re-bases the stamp without integrating.
        """
        last = self.stamp
        if last is not None and sample.stamp == last:
            return self
        if (last is None or not sample.usable()
                or not 0.0 < sample.stamp - last <= MAX_TRAVEL_SPAN):
            return Travel(self.x, self.y, self.theta, sample.stamp)
        dt = sample.stamp - last
        return Travel(self.x + sample.vx * dt, self.y + sample.vy * dt,
                      self.theta + sample.omega * dt, sample.stamp)


@dataclass(frozen=True, slots=True)
class SensorSnapshot:
    """Latest sample of each stream (``None`` until the first one arrives), plus each finger's
    integrated `Travel`.

    Sensor callbacks build a new snapshot (``snapshot.with_twist(1, sample)``, for every sample
    so the travel sees them all) and replace the node's reference in one assignment (CE-8);
    cores only read it.
    """

    wrench_1: WrenchSample | None = None
    wrench_2: WrenchSample | None = None
    twist_1: TwistSample | None = None
    twist_2: TwistSample | None = None
    travel_1: Travel = Travel()
    travel_2: Travel = Travel()

    def with_wrench(self, finger: int, sample: WrenchSample) -> SensorSnapshot:
        """Copy with finger ``finger``'s wrench replaced."""
        if finger == 1:
            return replace(self, wrench_1=sample)
        if finger == 2:
            return replace(self, wrench_2=sample)
        raise ValueError(f'finger must be 1 or 2, got {finger!r}')

    def with_twist(self, finger: int, sample: TwistSample) -> SensorSnapshot:
        """Copy with finger ``finger``'s twist replaced and its travel advanced."""
        if finger == 1:
            return replace(self, twist_1=sample, travel_1=self.travel_1.advanced(sample))
        if finger == 2:
            return replace(self, twist_2=sample, travel_2=self.travel_2.advanced(sample))
        raise ValueError(f'finger must be 1 or 2, got {finger!r}')


@dataclass(frozen=True, slots=True)
class InputStatus:
    """Freshness of the inputs at evaluation time ``t`` (CE-3).

    Attributes:
        velocity_fresh: Both twists present, usable and at most ``velocity_stale_after`` old.
        ft_fresh: Both wrenches present, finite and at most ``ft_stale_after`` old.
        synced: Finger-2 twist stamp within ``sync_tolerance`` of finger 1's.
        velocity_age: Age of the older twist [s] (inf if missing).
        ft_age: Age of the older wrench [s] (inf if missing).
    """

    velocity_fresh: bool
    ft_fresh: bool
    synced: bool
    velocity_age: float
    ft_age: float

    @property
    def all_fresh(self) -> bool:
        """Velocity and F/T fresh and the twists synchronised."""
        return self.velocity_fresh and self.ft_fresh and self.synced


def assess_inputs(snapshot: SensorSnapshot, t: float, *, velocity_stale_after: float,
                  ft_stale_after: float, sync_tolerance: float) -> InputStatus:
    """Judge staleness and synchronisation from stamps (CE-3).

    Args:
        snapshot: Latest samples.
        t: Evaluation time [s] (same clock as the stamps).
        velocity_stale_after: Maximum twist age [s].
        ft_stale_after: Maximum wrench age [s].
        sync_tolerance: Maximum ``|stamp2 − stamp1|`` of the twists [s].

    Returns:
        The freshness flags and ages. A sample stamped in the future (clock skew) has a
        negative age and counts as fresh.
    """
    t1, t2 = snapshot.twist_1, snapshot.twist_2
    if t1 is None or t2 is None or not (t1.usable() and t2.usable()):
        v_age = INF
        synced = False
    else:
        v_age = t - min(t1.stamp, t2.stamp)
        synced = abs(t2.stamp - t1.stamp) <= sync_tolerance
    w1, w2 = snapshot.wrench_1, snapshot.wrench_2
    if w1 is None or w2 is None or not (w1.finite() and w2.finite()):
        f_age = INF
    else:
        f_age = t - min(w1.stamp, w2.stamp)
    return InputStatus(velocity_fresh=v_age <= velocity_stale_after,
                       ft_fresh=f_age <= ft_stale_after, synced=synced,
                       velocity_age=v_age, ft_age=f_age)


#: Samples of the still-fresh stream that prove the stale one stopped (see `StaleDebounce`).
STOPPED_AFTER_SAMPLES = 4


class StaleDebounce:
    """Decides when a stale-input verdict is acted on: a stopped stream, not a backlog.

    A node that falls behind its queues (a busy 2-core machine, a GC pause) handles the timer
    or ``/clock`` update before the sensor samples queued with it, so for a moment its clock
    runs ahead of samples that are already on their way: an executor backlog, not a stopped
    stream. A verdict is acted on when either

    * the stale stream delivered nothing while the other stream delivered
      `STOPPED_AFTER_SAMPLES` samples (it stopped; the other one proves the node is being
      fed), or
    * it persisted ``confirm_s`` on a monotonic clock of the process (everything went quiet,
      or a stream stays late for longer than a backlog lasts).

    The staleness itself is still judged from stamps (CE-3); this only decides when the
    controller sees it.

    Args:
        confirm_s: Longest wait on the monotonic clock [s]; 0 = act at once.
    """

    def __init__(self, confirm_s: float) -> None:
        if not (confirm_s >= 0.0 and math.isfinite(confirm_s)):
            raise ValueError(f'confirm_s must be finite and >= 0, got {confirm_s!r}')
        self.confirm_s = confirm_s
        self._since: float | None = None
        self._counts = (0, 0)
        self.deferred = 0  #: steps held back so far (diagnostics)

    def defer(self, velocity_stale: bool, ft_stale: bool, now: float, velocity_samples: int,
              ft_samples: int) -> bool:
        """True when this step should wait for the verdict to be confirmed.

        Args:
            velocity_stale: The twists are stale now.
            ft_stale: The wrenches are stale now.
            now: Monotonic time [s].
            velocity_samples: Twists received so far (both fingers, a running count).
            ft_samples: Wrenches received so far (both fingers, a running count).
        """
        if not (velocity_stale or ft_stale):
            self._since = None
            return False
        if self._since is None:
            self._since = now
            self._counts = (velocity_samples, ft_samples)
        if now - self._since >= self.confirm_s:
            return False
        new_v = velocity_samples - self._counts[0]
        new_f = ft_samples - self._counts[1]
        if velocity_stale != ft_stale:
            stale_new, other_new = (new_v, new_f) if velocity_stale else (new_f, new_v)
            if stale_new == 0 and other_new >= STOPPED_AFTER_SAMPLES:
                return False
        self.deferred += 1
        return True


@dataclass(frozen=True, slots=True)
class MiddleWrench:
    """Two-finger mean wrench in ``gripper_middle`` (§1.2).

    Attributes:
        fx: Mean x force ``(Fx1' + Fx2')/2`` [N].
        fy: Mean y force [N].
        tz: Mean torque about +z ``(τ1' + τ2')/2`` [N·m].
        grasp_force: ``−(Fz1 + Fz2)/2`` [N] (raw frames; positive when squeezing).
        normal_force: ``(|Fz1| + |Fz2|)/2`` [N].
    """

    fx: float
    fy: float
    tz: float
    grasp_force: float
    normal_force: float

    @property
    def tangential_force(self) -> float:
        """``ft = ‖(F̄x, F̄y)‖`` [N], the per-finger tangential load."""
        return math.hypot(self.fx, self.fy)

    def limit_surface_load(self, r: float) -> float:
        """``D = ‖(F̄x, F̄y, τ̄/r)‖`` [N] (§4.4); ``r`` [m] must already be guarded (≥ 1e-5)."""
        return math.sqrt(self.fx * self.fx + self.fy * self.fy + (self.tz / r) ** 2)


@dataclass(frozen=True, slots=True)
class MiddleTwist:
    """Two-finger mean slip twist in ``gripper_middle`` (§1.2).

    Attributes:
        vx: Signed mean ``(vx1' + vx2')/2`` [m/s].
        vy: Signed mean [m/s].
        omega: Signed mean ``(ω1' + ω2')/2`` about +z [rad/s].
    """

    vx: float
    vy: float
    omega: float

    @property
    def speed(self) -> float:
        """``‖v̄‖`` [m/s] (equals the reference ``‖(|vx|, |vy|)‖``)."""
        return math.hypot(self.vx, self.vy)

    def slip_speed(self, r: float) -> float:
        """``v_s = ‖(v̄x, v̄y, r·ω̄)‖`` [m/s] for a torsional radius ``r`` [m]."""
        w = r * self.omega
        return math.sqrt(self.vx * self.vx + self.vy * self.vy + w * w)


def combine_wrenches(frames: FrameParams, w1: WrenchSample, w2: WrenchSample) -> MiddleWrench:
    """Mean wrench of both fingers in ``gripper_middle`` (§1.2).

    Args:
        frames: Frame constants (fixed sensor rotations).
        w1: Finger-1 wrench in ``ft_sensor_1``.
        w2: Finger-2 wrench in ``ft_sensor_2``.
    """
    x1, y1, z1 = planar_to_middle(frames, 1, w1.fx, w1.fy, w1.tz)
    x2, y2, z2 = planar_to_middle(frames, 2, w2.fx, w2.fy, w2.tz)
    return MiddleWrench(fx=0.5 * (x1 + x2), fy=0.5 * (y1 + y2), tz=0.5 * (z1 + z2),
                        grasp_force=-0.5 * (w1.fz + w2.fz),
                        normal_force=0.5 * (abs(w1.fz) + abs(w2.fz)))


def combine_twists(frames: FrameParams, v1: TwistSample, v2: TwistSample) -> MiddleTwist:
    """Mean slip twist of both fingers in ``gripper_middle`` (§1.2).

    Args:
        frames: Frame constants (fixed sensor rotations).
        v1: Finger-1 twist in ``vel_sensor_1``.
        v2: Finger-2 twist in ``vel_sensor_2``.
    """
    x1, y1, z1 = planar_to_middle(frames, 1, v1.vx, v1.vy, v1.omega)
    x2, y2, z2 = planar_to_middle(frames, 2, v2.vx, v2.vy, v2.omega)
    return MiddleTwist(vx=0.5 * (x1 + x2), vy=0.5 * (y1 + y2), omega=0.5 * (z1 + z2))


def middle_travel_delta(frames: FrameParams, before: tuple[Travel, Travel],
                        after: tuple[Travel, Travel]) -> MiddleTwist:
    """Mean slip displacement of both fingers in ``gripper_middle`` between two snapshots.

    Returns a `MiddleTwist` whose fields are displacements (``vx``, ``vy`` [m], ``omega``
    [rad]), not rates: the frame change of §1.2 is linear, so it applies to displacements too.
    """
    x1, y1, z1 = planar_to_middle(frames, 1, after[0].x - before[0].x,
                                  after[0].y - before[0].y, after[0].theta - before[0].theta)
    x2, y2, z2 = planar_to_middle(frames, 2, after[1].x - before[1].x,
                                  after[1].y - before[1].y, after[1].theta - before[1].theta)
    return MiddleTwist(vx=0.5 * (x1 + x2), vy=0.5 * (y1 + y2), omega=0.5 * (z1 + z2))
