"""``RigSettings``: how a :class:`real.PyAudioRig` plays and records, as one frozen value.

The rig validates its arguments and hands a snapshot of them to each recording or stream, so
what records never reads (or writes) the rig itself. Data only: imports nothing else of
``real``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RigSettings:
    """The rig's settings (see :class:`real.PyAudioRig` for their meaning and checks).

    Attributes:
        sample_rate_hz: sample rate, Hz.
        actuator_channel, mic_channel: output channel of the actuator, input channel of the
            contact microphone.
        output_channels, input_channels: channels opened on each device.
        frames_per_buffer: PortAudio buffer, frames.
        stream_mode: ``"separate"`` or ``"duplex"``.
        output_gain: scale of the excitation on the output (full scale 1).
        max_latency_s: longest wait for the excitation to come back, seconds.
        start_timeout_s: longest wait for the input's first samples, seconds.
        stall_timeout_s: silence of the input that means the device is gone, seconds.
        xrun_policy: ``"raise"``, ``"warn"`` or ``"ignore"``.
        sync_tolerance_samples: allowed spread of the per-period latency, samples.
        period_tolerance: allowed relative RMS difference between consecutive periods.
        lead_in_s: how long the output plays before its first period boundary, seconds.
        server_timeout_s: longest wait for a sound-server call that can block, seconds.
    """

    sample_rate_hz: int
    actuator_channel: int
    mic_channel: int
    output_channels: int
    input_channels: int
    frames_per_buffer: int
    stream_mode: str
    output_gain: float
    max_latency_s: float
    start_timeout_s: float
    stall_timeout_s: float
    xrun_policy: str
    sync_tolerance_samples: int
    period_tolerance: float
    lead_in_s: float
    server_timeout_s: float
