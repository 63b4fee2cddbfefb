"""When the grasp task records, and when an episode succeeds (``aas_gym/AcousticGrasp-v0`` and
``real.RealGraspEnv`` alike).

The cadence (``AcousticConfig.active_cadence``) decides what a step does with the sensor:

- ``"action"``: record ``duration_s`` when the sense entry of the action is positive; the
  episode succeeds when that recording was made through the grasp (grasped at the step's end
  and while recording);
- ``"every_step"``: record every step; no step ends the episode (there is no decision to stop);
- ``"never"``: pure control, no success;
- ``"stream"``: the microphone never stops; the sense entry asks to stop, which succeeds once
  the features the policy holds (those of the latest complete excitation period) come from a
  whole period recorded while the grasp held (:class:`GraspHold`).

The streamed rule is one both sides can evaluate: the grasp as the robot reports it at the end
of each step (a real rig cannot see its fingertips' contacts sample by sample), and stream
sample indices. A grasp first reported at the end of a step may have closed anywhere in it, so
it counts from that step's end: a period starting there or later was heard through the grasp.
"""

from __future__ import annotations

__all__ = ["GraspHold", "records_this_step", "step_success"]


def records_this_step(cadence: str, sense: bool) -> bool:
    """Whether a step records ``duration_s`` (cadences ``"action"`` and ``"every_step"``;
    a stream records anyway)."""
    return cadence == "every_step" or (cadence == "action" and sense)


class GraspHold:
    """From which stream sample the grasp has held without a break, as seen at step ends.

    Args:
        period_samples: samples in one excitation period (the features' window).
    """

    def __init__(self, period_samples: int) -> None:
        if int(period_samples) < 1:
            raise ValueError(f"period_samples must be >= 1, got {period_samples!r}")
        self.period_samples = int(period_samples)
        self.since_sample: int | None = None

    def reset(self) -> None:
        """A new episode (or stream): no grasp yet."""
        self.since_sample = None

    def update(self, grasped: bool, step_end_sample: int) -> None:
        """After a step: ``grasped`` at its end, the stream index of the step's last sample + 1."""
        if not grasped:
            self.since_sample = None
        elif self.since_sample is None:
            self.since_sample = int(step_end_sample)

    def heard_whole_period(self, latest_period: int) -> bool:
        """Whether period ``latest_period`` (samples ``[kP, (k+1)P)``; -1: none yet) was
        recorded entirely while the grasp held."""
        return (self.since_sample is not None and latest_period >= 0
                and latest_period * self.period_samples >= self.since_sample)


def step_success(cadence: str, *, sense: bool, grasped: bool, recording_grasped: bool = False,
                 heard_whole_period: bool = False) -> bool:
    """Whether this step ends the episode with success (see the module docstring).

    Args:
        cadence: the cadence in effect.
        sense: the action's sense entry was positive.
        grasped: both sensor fingertips press the object at the step's end.
        recording_grasped: cadence ``"action"``: the step's recording was made through the grasp.
        heard_whole_period: cadence ``"stream"``: :meth:`GraspHold.heard_whole_period` of
            the latest complete period.
    """
    if not (sense and grasped):
        return False
    if cadence == "action":
        return recording_grasped
    if cadence == "stream":
        return heard_whole_period
    return False
