"""The real audio path, for real: PyAudio -> ALSA -> PulseAudio null sink -> monitor -> PyAudio.

A session fixture (tests/conftest.py) starts a private PulseAudio server (``real.loopback``);
the tests play each excitation and record it back, check latency, window alignment and
features, feed the recordings to a classifier trained on simulated-source observations,
record a leak, and inject faults (no device, device vanishing mid-recording, unsupported rate,
killed process).
Needs Debian pulseaudio + libasound2-plugins (+ portaudio19-dev for PyAudio).
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyaudio")
if not (Path("/usr/bin/pulseaudio").exists() or os.environ.get("AAS_PULSE_BIN")):
    pytest.skip("PulseAudio is not installed (apt-get install pulseaudio libasound2-plugins)",
                allow_module_level=True)

import real  # noqa: E402
import sensors  # noqa: E402
from real import loopback  # noqa: E402

# One PulseAudio server per test process (`audio_loopback`, tests/conftest.py), which some
# tests kill and restart: the tests that play or record audio are in this file and
# test_real_stream.py, each on one worker under `pytest-xdist --dist loadfile` (the group
# mark does the same for `--dist loadgroup`).
pytestmark = [pytest.mark.audio, pytest.mark.slow, pytest.mark.xdist_group("real_audio")]
EXCITATIONS = ["impulse", "linear", "exponential"]
GAIN = 0.5  # headroom: a full-scale loopback reads exactly 1.0, which the rig flags as clipping
DURATION_S = 1.0


def _restore(lb) -> None:
    loopback.start_loopback(lb.sink, runtime_dir=lb.runtime_dir)


@pytest.fixture(scope="module")
def rig(audio_loopback):
    # 4096-frame buffers (93 ms): the callbacks keep up on a loaded machine, where 1024 (23 ms)
    # underflows and the rig rightly refuses the recording
    return real.PyAudioRig(output_gain=GAIN, frames_per_buffer=4096)


@pytest.fixture(scope="module")
def recordings(rig):
    """One 1 s recording per excitation (shared by the tests that only read them)."""
    sensor = real.RealAcousticSensor(rig)
    out = {}
    for name in EXCITATIONS:
        obs = sensor.sense(name, DURATION_S, labels={"object": "loopback"})
        out[name] = (obs, rig.last_recording)
    return out


def test_list_devices_and_default_rig(rig):
    devices = real.list_devices()
    names = [d.name for d in devices]
    assert "default" in names and "pulse" in names
    assert any(d.is_default_input for d in devices) and any(d.is_default_output for d in devices)
    assert rig.input_device.name == "default"
    # by name substring and by index
    by_name = real.PyAudioRig("puls", "puls")
    assert by_name.input_device.name == "pulse"
    assert real.PyAudioRig(by_name.input_device.index).input_device.name == "pulse"


@pytest.mark.parametrize("name", EXCITATIONS)
def test_round_trip_latency_alignment_and_features(recordings, name):
    obs, rec = recordings[name]
    ex = sensors.Excitation.by_name(name)
    sample_rate_hz = ex.sample_rate_hz
    # latency found, every period at the same lag: sample-synchronized
    assert rec.latency_samples is not None and 0 < rec.latency_s < 2.0
    assert len(rec.period_lags_samples) >= 2 and rec.drift_samples == 0
    assert set(rec.period_lags_samples) == {rec.latency_samples}
    assert not any(c for k, c in rec.flag_counts().items() if k != "priming_output")
    # windows aligned: the trimmed recording IS the played loop, sample for sample
    expected = GAIN * ex.loop(DURATION_S)
    assert obs.waveform.shape == expected.shape and obs.waveform.dtype == np.float32
    np.testing.assert_allclose(obs.waveform, expected, rtol=0, atol=1e-6)
    assert obs.start_time_s == 0.0
    # the same 140 features as the excitation itself, within a tight tolerance
    f_ref = sensors.AcousticObservation(expected, sample_rate_hz, ex).features()
    f_real = obs.features()
    assert f_real.shape == (140,)
    np.testing.assert_allclose(f_real, f_ref, rtol=1e-5, atol=1e-7 * f_ref.max())
    # untrimmed: start_time_s is the latency, and the features agree too
    raw = rec.to_observation(trim=False)
    assert raw.start_time_s == pytest.approx(rec.latency_samples / sample_rate_hz)
    np.testing.assert_allclose(raw.features(), f_ref, rtol=1e-5, atol=1e-7 * f_ref.max())
    meta = obs.metadata
    assert meta["source"] == "real" and meta["complete"] and not meta["partial"]
    assert meta["device"]["input"]["name"] == "default" and meta["latency_samples"] == rec.latency_samples
    assert meta["labels"] == {"object": "loopback"} and meta["excitation"] == ex.name
    assert meta["recorded_at"].endswith("+00:00")
    json.dumps(meta)  # plain JSON


def _sim_source_observations(n_per_class: int = 4):
    """Simulated-source observations built with the sensors API: the excitation through two
    damped resonators per class (a stand-in for modal synthesis with the same layout)."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(0)
    X_obs, y = [], []
    for label, modes_hz in (("aluminium", (4200.0, 7300.0)), ("wood", (3600.0, 8800.0))):
        for _ in range(n_per_class):
            for name in EXCITATIONS:
                ex = sensors.Excitation.by_name(name)
                drive = ex.loop(DURATION_S + ex.period_s)
                out = np.zeros_like(drive)
                for f in modes_hz:
                    f = f * (1 + 0.01 * rng.standard_normal())
                    r, w = np.exp(-200.0 / ex.sample_rate_hz), 2 * np.pi * f / ex.sample_rate_hz
                    out += lfilter([1.0], [1.0, -2 * r * np.cos(w), r * r], drive)
                # keep the steady state: drop the first period (the simulator does the same)
                wave = out[ex.period_samples:] * 1e-2 + 1e-5 * rng.standard_normal(out.size - ex.period_samples)
                X_obs.append(sensors.AcousticObservation(wave, ex.sample_rate_hz, ex, metadata={"source": "sim"}))
                y.append(label)
    return X_obs, np.array(y)


def test_classifier_trained_on_sim_accepts_real_observations(recordings):
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    sim_obs, y = _sim_source_observations()
    real_obs = [recordings[name][0] for name in EXCITATIONS]
    # same layout: shapes, dtypes, sample rate, alignment, feature bins
    for o in real_obs:
        s = next(x for x in sim_obs if x.excitation == o.excitation)
        assert o.waveform.shape == s.waveform.shape and o.waveform.dtype == s.waveform.dtype == np.float32
        assert o.sample_rate_hz == s.sample_rate_hz and o.start_time_s == s.start_time_s == 0.0
        assert o.features().shape == s.features().shape == (140,)
        assert o.features().dtype == s.features().dtype
    # (a) raw waveforms through sensors.SpectralFeatures
    raw_clf = make_pipeline(sensors.SpectralFeatures(scale="db"), StandardScaler(), KNeighborsClassifier(3))
    raw_clf.fit(np.stack([o.waveform for o in sim_obs]), y)
    pred_raw = raw_clf.predict(np.stack([o.waveform for o in real_obs]))
    # (b) on .features()
    feat_clf = make_pipeline(StandardScaler(), KNeighborsClassifier(3))
    feat_clf.fit(np.stack([o.features() for o in sim_obs]), y)
    pred_feat = feat_clf.predict(np.stack([o.features() for o in real_obs]))
    assert pred_raw.shape == pred_feat.shape == (3,) and set(pred_raw) <= {"aluminium", "wood"}
    names = raw_clf[0].get_feature_names_out()
    assert names[0] == "amp_3000hz" and names[-1] == "amp_9950hz"


def test_classifier_trained_on_sim_acoustic_sensor_accepts_real(recordings):
    """The same with aas_gym.SimAcousticSensor's own observations (the full simulator)."""
    gym = pytest.importorskip("gymnasium")
    import aas_gym  # noqa: F401
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.pipeline import make_pipeline

    X, y = [], []
    for obj in ("aluminium_bar", "wood_bar"):
        env = gym.make("aas_gym/GraspPosition-v0", objects=[obj],
                       acoustic={"duration_s": DURATION_S, "excitation": "linear", "waveform": True})
        for seed in range(2):
            o, _ = env.reset(seed=seed)  # grasps and senses through aas_gym.SimAcousticSensor
            X.append(o["waveform"])
            y.append(obj)
        env.close()
    real_obs = recordings["linear"][0]
    assert X[0].shape == real_obs.waveform.shape and X[0].dtype == real_obs.waveform.dtype
    clf = make_pipeline(sensors.SpectralFeatures(scale="db"), KNeighborsClassifier(1))
    clf.fit(np.stack(X), y)
    assert clf.predict(real_obs.waveform[None])[0] in {"aluminium_bar", "wood_bar"}


def test_leak_recording_loads_in_the_simulator_format(rig, tmp_path):
    from sensors.signals.leak import align_leak, load_leak

    sensor = real.RealAcousticSensor(rig)
    ex = sensors.Excitation.by_name("exponential")
    path = sensor.record_leak(ex, tmp_path / "leak_exponential", duration_s=DURATION_S)
    assert path.name == "leak_exponential.npz" and sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    leak = load_leak(path)
    assert leak.matches(ex) and leak.sample_rate_hz == ex.sample_rate_hz
    assert leak.metadata["kind"] == "leak" and leak.metadata["source"] == "real"
    aligned = align_leak(leak, ex, ex.period_samples)
    np.testing.assert_allclose(aligned, GAIN * ex.signal, atol=1e-6)


def test_saved_recording_is_whole_and_partial_files_are_gone(rig, tmp_path):
    sensor = real.RealAcousticSensor(rig, save_dir=tmp_path, labels={"run": 1})
    obs = sensor.sense("impulse", 0.5)
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == [sensor.last_path.name] and files[0].endswith("_impulse.npz")
    back = sensors.AcousticObservation.load(sensor.last_path)
    np.testing.assert_array_equal(back.waveform, obs.waveform)
    assert back.metadata["labels"] == {"run": 1} and back.metadata["complete"]


def _fault_during_recording(rig, tmp_path, fault, after_s=1.0):
    """Record 5 s; once ``after_s`` of audio is in, run ``fault()`` from another thread.
    Returns the ``DeviceLostError`` and how many frames had arrived before the fault.

    Under CPU load the loopback may underrun before the fault is injected; the rig then
    (rightly) raises ``XrunError`` and the run tested nothing about the fault: it is tried
    again, at most three times. An xrun after the fault fails the test."""
    ex = sensors.Excitation.by_name("linear")
    for attempt in range(3):
        for p in tmp_path.iterdir():
            p.unlink()
        started, injected, cancelled = threading.Event(), threading.Event(), threading.Event()
        frames_seen, frames_before_fault = [0], [0]

        def progress(frames):
            frames_seen[0] = frames
            if frames >= after_s * ex.sample_rate_hz:
                started.set()

        def inject():
            if started.wait(15) and not cancelled.is_set():
                frames_before_fault[0] = frames_seen[0]
                fault()
                injected.set()

        t = threading.Thread(target=inject)
        t.start()
        try:
            rig.record(ex, 5.0, save_path=tmp_path / "rec.npz", on_progress=progress)
        except real.DeviceLostError as exc:
            return exc, frames_before_fault[0]
        except real.XrunError:
            if injected.is_set() or attempt == 2:
                raise
        finally:
            cancelled.set()  # a run that ended before the fault must not leave the injector waiting
            started.set()
            t.join()
    pytest.fail("the recording did not fail when the device went away")


@pytest.mark.parametrize("how", ["unload_sink", "kill_server"])
def test_device_vanishing_mid_recording_keeps_what_was_recorded(rig, audio_loopback, tmp_path, how):
    rt = audio_loopback.runtime_dir
    fault = (lambda: loopback.unload_sink(runtime_dir=rt)) if how == "unload_sink" else (
        lambda: loopback.stop_loopback(rt))
    try:
        err, before_fault = _fault_during_recording(rig, tmp_path, fault)
    finally:
        _restore(audio_loopback)
    assert "'default'" in str(err) and err.device == "default"
    rec = err.recording
    assert not rec.complete and rec.input.shape[0] >= 1.0 * 44100
    # the partial file holds every sample recorded, and says it is partial
    assert err.partial_path.name == "rec.partial.npz" and str(err.partial_path) in str(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.partial.npz"]
    part = sensors.AcousticObservation.load(err.partial_path)
    np.testing.assert_array_equal(part.waveform, rec.mic)
    assert part.metadata["partial"] and not part.metadata["complete"] and "DeviceLostError" in part.metadata["error"]
    # and what was recorded before the fault is the excitation, in sync, or the recording says
    # it is not (an underflow under load can damage the first period). Samples from the moment
    # the device goes away on are the error's, not a silent damage: the first period (1 s, from
    # the latency on) runs past the fault injected after 1 s, so it is compared up to the fault.
    assert rec.latency_samples is not None and before_fault > rec.latency_samples
    ex = rec.excitation
    seg = part.waveform[rec.latency_samples:min(rec.latency_samples + ex.period_samples, before_fault)]
    if not np.allclose(seg, GAIN * ex.signal[:seg.size], atol=1e-6):
        assert rec.problems, "a damaged recording must report it"
    # the restarted server works again
    assert real.RealAcousticSensor(rig).sense("impulse", 0.5).metadata["complete"]


def test_unsupported_sample_rate_names_the_device(audio_loopback):
    with pytest.raises(real.UnsupportedSampleRateError, match=r"'default' \(index \d+, ALSA\).*1000000 Hz") as info:
        real.PyAudioRig(sample_rate_hz=1_000_000)
    assert info.value.device == "default"


def test_unknown_device_lists_the_available_ones(audio_loopback):
    with pytest.raises(real.DeviceNotFoundError, match=r"no input device named like 'focusrite'.*'pulse'"):
        real.PyAudioRig("focusrite")
    with pytest.raises(real.DeviceNotFoundError, match="index 99"):
        real.PyAudioRig(output_device=99)


def test_no_audio_device(audio_loopback):
    loopback.stop_loopback(audio_loopback.runtime_dir)
    try:
        left = real.list_devices()
        if left:
            pytest.skip(f"this machine has audio devices besides the loopback: {[d.name for d in left]}")
        with pytest.raises(real.NoAudioDeviceError, match="no audio device.*system default") as info:
            real.PyAudioRig()
        assert info.value.device == "default"
        with pytest.raises(real.NoAudioDeviceError, match="'pulse'"):
            real.PyAudioRig("pulse")
    finally:
        _restore(audio_loopback)
    assert real.list_devices()


def test_killed_process_leaves_a_recoverable_partial_file_not_a_whole_one(audio_loopback, tmp_path):
    target = tmp_path / "take.npz"
    code = (
        "import real, sensors\n"
        "rig = real.PyAudioRig(output_gain=0.5)\n"
        f"rig.record(sensors.Excitation.by_name('linear'), 30.0, save_path={str(target)!r})\n"
    )
    env = {**os.environ, **audio_loopback.env(), "PYTHONPATH": str(Path(real.__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, "-c", code], env=env, stderr=subprocess.DEVNULL)
    raw = tmp_path / "take.partial.f32"
    deadline = time.monotonic() + 30
    while (not raw.exists() or raw.stat().st_size < 4 * 44100) and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not target.exists()  # never a whole-looking file
    assert (tmp_path / "take.partial.json").exists() and raw.stat().st_size >= 4 * 44100
    n_raw = raw.stat().st_size // 4
    path = real.recover_partial(target)
    assert path.name == "take.partial.npz" and sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    obs = sensors.AcousticObservation.load(path)
    assert obs.metadata["partial"] and obs.waveform.size == n_raw
    lat = real.find_latency(obs.waveform, obs.excitation)
    assert lat is not None


def test_xrun_policy_on_a_drifting_full_duplex_stream(audio_loopback):
    """PortAudio's full-duplex stream through ALSA's pulse plugin drops/inserts samples on
    this kind of machine; whatever it does, the rig's sync check tells the truth."""
    rig = real.PyAudioRig(output_gain=GAIN, stream_mode="duplex", xrun_policy="warn")
    ex = sensors.Excitation.by_name("linear")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            rec = rig.record(ex, 1.5)
        except real.DeviceLostError as exc:
            # Under load ALSA's pulse plugin can stop a duplex stream for good: the rig says
            # so, naming it, and hands back what it recorded (seen once in 4 loaded runs).
            assert "duplex stream" in str(exc) and exc.recording is not None and not exc.recording.complete
            return
    # The rig judges the whole kept recording (1.5 s after the latency, every complete
    # period) by alignment and period-to-period consistency; here each period is compared
    # with the truth, the excitation itself.
    kept = rec.mic[rec.latency_samples:rec.latency_samples + int(round(1.5 * ex.sample_rate_hz))]
    P = ex.period_samples
    periods = kept[: kept.size // P * P].reshape(-1, P)
    truth = GAIN * ex.signal
    error = np.sqrt(((periods - truth) ** 2).mean(axis=1)) / np.sqrt((truth ** 2).mean())
    exact = np.allclose(periods, truth, atol=1e-6)
    rig_warned = any(issubclass(w.category, real.RigWarning) for w in caught)
    assert rig_warned == bool(rec.problems)
    if exact:       # an exact recording is not reported
        assert not rig_warned, rec.problems
    if not rig_warned:  # an unreported one is usable: aligned, every period within tolerance
        assert len(set(rec.period_lags_samples)) == 1 and error.max() <= rig.period_tolerance, error
    assert rec.complete and rec.stream_mode == "duplex"


def test_cli_record_and_record_leak(audio_loopback, tmp_path, capsys):
    from real import cli

    assert cli.main(["audio-devices"]) == 0
    assert "default" in capsys.readouterr().out
    out = tmp_path / "take.npz"
    assert cli.main(["record", "-e", "impulse", "-s", "0.5", "--gain", "0.5", "-o", str(out),
                     "--label", "object=none"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.npz"]
    obs = sensors.AcousticObservation.load(out)
    assert obs.waveform.size == 22050 and obs.metadata["labels"] == {"object": "none"}
    assert obs.metadata["kind"] == "recording"
    assert cli.main(["record-leak", "-o", str(tmp_path / "leaks"), "--excitations", "linear", "-s", "0.5",
                     "--gain", "0.5"]) == 0
    from sensors.signals.leak import load_leak

    assert load_leak(tmp_path / "leaks" / "leak_linear.npz").matches(sensors.Excitation.by_name("linear"))
    assert cli.main(["record", "--input", "no-such-card", "-o", str(tmp_path / "x.npz")]) == 1
    assert "no input device named like 'no-such-card'" in capsys.readouterr().err


def test_output_underrun_is_detected_and_raised(audio_loopback, tmp_path):
    """Starve PortAudio's callback thread of the GIL for 0.4 s mid-recording: the output
    underruns. The flag and the broken sample synchronization are both reported, and the
    recording is kept (in the error and as a partial file)."""
    rig = real.PyAudioRig(output_gain=GAIN, xrun_policy="raise")
    ex = sensors.Excitation.by_name("linear")
    done = []

    def hog_the_gil(frames):
        if frames >= 0.7 * ex.sample_rate_hz and not done:
            done.append(True)
            old = sys.getswitchinterval()
            sys.setswitchinterval(1.0)  # no other Python thread (the callbacks) runs meanwhile
            try:
                t = time.perf_counter()
                while time.perf_counter() - t < 0.4:
                    pass
            finally:
                sys.setswitchinterval(old)

    with pytest.raises(real.XrunError, match="'default'.*synchronization lost|'default'.*underflow") as info:
        rig.record(ex, 2.0, save_path=tmp_path / "u.npz", on_progress=hog_the_gil)
    rec = info.value.recording
    assert rec.drift_samples > 0 or rec.flag_counts()["output_underflow"] > 0
    assert rec.input.shape[0] >= 2.0 * ex.sample_rate_hz and rec.problems
    part = sensors.AcousticObservation.load(info.value.partial_path)
    assert part.metadata["partial"] and part.metadata["problems"] == rec.problems


def test_grasp_and_sense_through_the_real_audio_path(audio_loopback):
    from aas_gym.robot import MujocoRobot
    from real.env import RealGraspEnv
    from scripted_policy import reach_and_grasp

    robot = MujocoRobot(randomization=False)
    sensor = real.RealAcousticSensor(real.PyAudioRig(output_gain=0.5, frames_per_buffer=4096))  # see the rig fixture
    env = RealGraspEnv(robot, sensor, acoustic={"excitation": "linear", "duration_s": 1.0})
    obs, _ = env.reset(seed=1)
    obs = reach_and_grasp(env, obs)
    obs, reward, terminated, truncated, info = env.step(np.array([0, 0, 0, 0, -1, 1], np.float32))
    assert terminated and info["is_success"]
    meta = info["recording_metadata"]
    assert meta["source"] == "real" and meta["complete"] and meta["sync"]["drift_samples"] == 0
    np.testing.assert_allclose(obs["acoustic"], env.last_recording.features().astype(np.float32))
    assert env.observation_space.contains(obs) and obs["acoustic"].max() > 0
    robot.close()


def test_loopback_restarts_right_after_its_server_was_killed(tmp_path):
    """A SIGKILLed server leaves its pid file and socket behind; the next start cleans up
    instead of failing with "Daemon already running"."""
    import os
    import signal
    import time

    lb = loopback.start_loopback(runtime_dir=tmp_path / "p", set_environ=False)
    try:
        os.kill(lb.pid, signal.SIGKILL)
        time.sleep(0.05)
        again = loopback.start_loopback(runtime_dir=tmp_path / "p", set_environ=False)
        assert again.pid != lb.pid and loopback.is_running(tmp_path / "p")
    finally:
        loopback.stop_loopback(tmp_path / "p")


_STALL_CHILD = """
import sys, time, real, sensors
rig = real.PyAudioRig(output_gain=0.5)
ex = sensors.Excitation.by_name("linear")
for attempt in ("during", "after"):
    t = time.monotonic()
    try:
        rig.record(ex, 30.0, save_path=sys.argv[1] if attempt == "during" else None)
        print(attempt, "returned", flush=True)
    except real.RigError as exc:
        print(attempt, type(exc).__name__, round(time.monotonic() - t, 1), str(exc).replace(chr(10), " "), flush=True)
"""


def test_a_stalled_sound_server_does_not_hang_the_recording(audio_loopback, tmp_path):
    """Issue 17 item 6. SIGSTOP the server 1 s into a recording and keep it stopped: the
    recording (in a child process, whose PortAudio stays blocked until the server answers)
    returns while the server is still stopped, with what was recorded saved; a recording
    started during the stall fails at once instead of queueing behind the blocked calls.
    Before, the child hung in PortAudio for as long as the server was stopped."""
    # the server now running (an earlier test may have restarted it under a new pid)
    pid = loopback.start_loopback(audio_loopback.sink, runtime_dir=audio_loopback.runtime_dir).pid
    assert pid > 0  # never signal -1 (every process)
    target = tmp_path / "take.npz"
    env = {**os.environ, **audio_loopback.env(), "PYTHONPATH": str(Path(real.__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, "-c", _STALL_CHILD, str(target)], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    out, hung = "", False
    try:
        raw = tmp_path / "take.partial.f32"
        deadline = time.monotonic() + 60
        while (not raw.exists() or raw.stat().st_size < 4 * 44100) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert raw.exists(), "the child never started recording"
        os.kill(pid, signal.SIGSTOP)
        try:  # about 5 s: stall_timeout_s + server_timeout_s, then server_timeout_s
            out, _ = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            hung = True
    finally:
        os.kill(pid, signal.SIGCONT)
        if proc.poll() is None:
            proc.kill()
            out = proc.communicate()[0]
    assert not hung, f"the recording hung while the sound server was stopped: {out}"
    lines = dict(line.split(" ", 1) for line in out.splitlines())
    print(f"stalled server: {lines}")
    assert proc.returncode == 0, out
    assert lines["during"].startswith("DeviceLostError"), out
    assert lines["after"].startswith("DeviceLostError") and any(
        why in lines["after"] for why in ("still closing the streams", "still terminating", "did not answer within")), out
    part = sensors.AcousticObservation.load(tmp_path / "take.partial.npz")
    assert part.metadata["partial"] and "DeviceLostError" in part.metadata["error"]
    assert part.waveform.size >= 44100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.partial.npz"]
    # the server answers again (xruns of a loaded machine are not the question here)
    rec = real.PyAudioRig(output_gain=GAIN, xrun_policy="ignore").record(sensors.Excitation.by_name("impulse"), 0.5)
    assert rec.complete and rec.latency_samples is not None


_FULL_DISK_CHILD = """
import json, os, resource, signal, sys
from pathlib import Path
import numpy as np, real, sensors
disk, out, limit = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG, as on a full disk
rig = real.PyAudioRig(output_gain=0.5, stall_timeout_s=5.0)  # a loaded machine is not the question here
ex = sensors.Excitation.by_name("linear")
soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))  # no file of this process grows past `limit` bytes
report = {"raised": None}
try:
    try:
        rig.record(ex, 1.0, save_path=disk / "take.npz")
    except real.StorageError as err:
        rec = err.recording
        report.update(raised=type(err).__name__, is_os_error=isinstance(err, OSError), errno=err.errno,
                      message=str(err), partial_path=str(err.partial_path), device=err.device,
                      is_last=rec is rig.last_recording)
        try:  # recovering beside the partial files, on the same full disk
            real.recover_partial(disk / "take.npz")
            report["again"] = None
        except real.StorageError as again:
            report["again"] = [again.errno, str(again)]
        report["files_while_full"] = sorted(os.listdir(disk))
finally:
    resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
if report["raised"]:
    report.update(complete=rec.complete, latency=rec.latency_samples)
    np.save(out / "input.npy", rec.input)
    rec.save(out / "whole.npz")  # the whole recording, from memory, on a disk with room
print(json.dumps(report))
"""


def test_a_full_disk_during_a_recording_loses_nothing(audio_loopback, tmp_path):
    """Issue 17 item 1. The recording's process may write at most 64 KiB per file
    (RLIMIT_FSIZE, in a child process: no root, no tmpfs), about 0.37 s of the streamed
    partial file. Before, the first refused write ended the recording and the error path
    failed again on the same disk. Now the recording finishes in memory and comes back on
    StorageError with what fitted on disk, an exact prefix; recovery on the full disk says
    so and keeps the raw files, recovery elsewhere works."""
    limit = 64 * 1024
    disk, out = tmp_path / "disk", tmp_path / "out"
    out.mkdir()
    env = {**os.environ, **audio_loopback.env(), "PYTHONPATH": str(Path(real.__file__).parents[1])}
    proc = subprocess.run([sys.executable, "-c", _FULL_DISK_CHILD, str(disk), str(out), str(limit)], env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.splitlines()[-1])
    assert report["raised"] == "StorageError", report
    assert report["is_os_error"] and report["errno"] == errno.EFBIG and report["device"] == "default"
    raw = disk / "take.partial.f32"
    assert report["partial_path"] == str(raw) and str(raw) in report["message"] and report["is_last"]
    # the recording finished, whole, in memory
    rec_input = np.load(out / "input.npy")
    assert report["complete"] and report["latency"] is not None
    # what fitted on the disk: exactly the first samples, up to the limit
    on_disk = np.fromfile(raw, dtype="<f4")
    assert on_disk.size == limit // 4 < rec_input.shape[0]
    np.testing.assert_array_equal(on_disk, rec_input[:on_disk.size, 0])
    # recovery on the still-full disk: a clear error, nothing removed
    errno_again, message_again = report["again"]
    assert errno_again == errno.EFBIG and "out_dir" in message_again
    assert report["files_while_full"] == ["take.partial.f32", "take.partial.json"]
    # recovery elsewhere, which empties the full disk
    part_path = real.recover_partial(disk / "take.npz", out_dir=tmp_path / "elsewhere")
    assert part_path == tmp_path / "elsewhere" / "take.partial.npz" and list(disk.iterdir()) == []
    part = sensors.AcousticObservation.load(part_path)
    assert part.metadata["partial"] and not part.metadata["complete"]
    np.testing.assert_array_equal(part.waveform, on_disk)
    # and the whole recording saved from memory is the kept span of what was recorded
    whole = sensors.AcousticObservation.load(out / "whole.npz")
    lat, n = report["latency"], int(round(1.0 * 44100))
    np.testing.assert_array_equal(whole.waveform, rec_input[lat:lat + n, 0])


def test_the_null_sink_is_kept_clocked_through_an_unplug(tmp_path):
    """``real.loopback``: a silent module stream plays into the null sink (an idle null sink
    renders in 2 s blocks, and a recording started then waited that long for its first input);
    it goes with the sink when the sink is unloaded (a device unplugged) and comes back with it;
    no client owns it."""
    lb = loopback.start_loopback(runtime_dir=tmp_path / "pulse", set_environ=False)
    env = {**os.environ, **lb.env()}

    def module_streams_into_sink() -> list[list[str]]:
        sinks = subprocess.run(["pactl", "list", "short", "sinks"], env=env, capture_output=True, text=True,
                               timeout=10, check=True).stdout
        index = {f[1]: f[0] for f in (line.split("\t") for line in sinks.splitlines())}
        inputs = subprocess.run(["pactl", "list", "short", "sink-inputs"], env=env, capture_output=True,
                                text=True, timeout=10, check=True).stdout
        return [f for f in (line.split("\t") for line in inputs.splitlines())
                if f[1:2] == [index.get(lb.sink)] and f[2:4] == ["-", "module-loopback.c"]]

    try:
        assert len(module_streams_into_sink()) == 1
        loopback.unload_sink(lb.sink, lb.runtime_dir)
        assert not loopback.sink_loaded(lb.sink, lb.runtime_dir)
        loopback.load_sink(lb.sink, runtime_dir=lb.runtime_dir)
        assert len(module_streams_into_sink()) == 1
    finally:
        loopback.stop_loopback(lb.runtime_dir)
