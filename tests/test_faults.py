"""The fault model, one test per promise: what a kill, a corrupt or foreign input or an
unwritable folder does to the files the project writes.

Covered elsewhere: kill -9 and resume of generation (test_generate), the real rig's partial
recordings (test_real_latency, test_real_audio), corrupt leak files at gym.make (test_env),
the CLI's failures (test_cli)."""

from __future__ import annotations

import errno
import os
import stat
import threading

import numpy as np
import pytest

from sensors._infra.atomic import atomic_open, atomic_savefig, atomic_write_text


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_written_files_follow_the_users_umask(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        atomic_write_text(tmp_path / "report.md", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "report.md").stat().st_mode) == mode


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "results.json"
    atomic_write_text(path, "old")
    with pytest.raises(RuntimeError):
        with atomic_open(path, "w") as fh:
            fh.write("half of the new")
            raise RuntimeError("killed mid-write")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]


def test_figures_are_written_whole(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot(np.arange(3))
    atomic_savefig(fig, tmp_path / "f.png", dpi=50)
    plt.close(fig)
    assert (tmp_path / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["f.png"]


def test_a_foreign_or_corrupt_leak_file_is_named(tmp_path):
    from sensors import load_leak

    bad = tmp_path / "leak.npz"
    bad.write_bytes(os.urandom(256))
    with pytest.raises(ValueError, match="leak.npz"):
        load_leak(bad)
    np.save(tmp_path / "array.npy", np.zeros(3))
    (tmp_path / "array.npy").rename(tmp_path / "other.npz")
    with pytest.raises(ValueError, match="other.npz"):
        load_leak(tmp_path / "other.npz")
    np.savez(tmp_path / "foreign.npz", something=np.zeros(3))
    with pytest.raises(ValueError, match="foreign.npz.*not a leak recording"):
        load_leak(tmp_path / "foreign.npz")


def _garbage_files(tmp_path):
    rnd = tmp_path / "random.npz"
    rnd.write_bytes(os.urandom(300))
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, something=np.zeros(3))
    return [rnd, foreign]


def test_corrupt_or_foreign_observation_and_model_files_are_named(tmp_path):
    from sensors import AcousticObservation, FileFormatError, ModalModel

    for path in _garbage_files(tmp_path):
        with pytest.raises(FileFormatError, match=path.name + ".*observation"):
            AcousticObservation.load(path)
        with pytest.raises(FileFormatError, match=path.name + ".*modal model"):
            ModalModel.load(path)


def test_a_model_file_with_nan_frequencies_is_refused(tmp_path):
    from sensors import MATERIALS, FileFormatError, ModalModel
    from sensors.modal import io as modal_io

    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]) * 0.01
    good = ModalModel(nodes, [[0, 1, 2, 3]], [1000.0, 2000.0], np.ones((4, 3, 2)), MATERIALS["steel"])
    arrays = modal_io.to_arrays(good)
    for name, bad in (("nan", np.array([np.nan, 2000.0])), ("descending", np.array([2000.0, 1000.0]))):
        np.savez(tmp_path / f"{name}.npz", **dict(arrays, frequencies_hz=bad))
        with pytest.raises(FileFormatError, match=f"{name}.npz"):
            ModalModel.load(tmp_path / f"{name}.npz")
    np.savez(tmp_path / "ok.npz", **arrays)
    assert ModalModel.load(tmp_path / "ok.npz").n_modes == 2


def test_observations_record_the_leak_file_by_name_and_hash_not_path(tmp_path):
    """Datasets and recordings must not carry the user's directory layout."""
    import hashlib

    from sensors import Contact, Excitation, LeakRecording, ModalModel, MATERIALS, save_leak, simulate_recording

    ex = Excitation.impulse()
    path = save_leak(tmp_path / "private" / "leak_impulse", np.zeros(ex.period_samples, np.float32), ex.sample_rate_hz, ex)
    model = ModalModel.bar(0.2, 0.02, 0.02, MATERIALS["steel"], progress=False)
    act = Contact([0.0, 0.01, 0.0], [0, 1, 0], 40.0, 0.5)
    mic = Contact([0.0, -0.01, 0.0], [0, -1, 0], 40.0, 0.5)
    obs = simulate_recording(model, ex, 0.5, act, mic, leak=path)
    assert obs.metadata["leak_file"] == {"name": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}
    assert str(tmp_path) not in repr(obs.metadata)


def test_loaders_refuse_what_they_would_change_silently(tmp_path):
    """Each of these used to load as something else: 32768x PCM, a truncated sample rate,
    1 Pa from `true`, inf from 1e300, all-NaN features from 1e308."""
    import json

    from sensors import AcousticObservation, Excitation, LeakRecording, Material, load_leak, spectral_features

    ex = Excitation.impulse()
    with pytest.raises(TypeError, match="32768"):
        LeakRecording(np.zeros(100, np.int16), 44100, ex)
    np.savez(tmp_path / "odd_rate.npz", waveform=np.zeros(100, np.float32), sample_rate_hz=np.array(44100.7),
             excitation=np.array(json.dumps(ex.to_dict())))
    with pytest.raises(ValueError, match="odd_rate.npz.*sample_rate_hz"):
        load_leak(tmp_path / "odd_rate.npz")
    d = dict(Material("x", 1000.0, 1e9, 0.3, 1.0, 1e-7, 0.1).to_dict(), youngs_modulus_pa=True)
    with pytest.raises(ValueError, match="youngs_modulus_pa must be a number"):
        Material.from_dict(d)
    with pytest.raises(ValueError, match="float32"):
        AcousticObservation(np.full(22050, 1e300), 44100, ex)
    with pytest.raises(ValueError, match="too large"):
        spectral_features(np.full(22050, 1e308), 44100)


def _children(pid: int) -> set[int]:
    """Every descendant of ``pid`` (from /proc)."""
    from pathlib import Path

    parents = {}
    for stat_file in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat_file.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parents[int(stat_file.parent.name)] = int(fields[1])
    out, frontier = set(), {pid}
    while frontier:
        frontier = {c for c, p in parents.items() if p in frontier} - out
        out |= frontier
    return out


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to list processes")
def test_kill_9_of_generate_leaves_no_worker_behind(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    proc = subprocess.Popen([sys.executable, "-m", "aas_gym.cli", "generate", str(tmp_path / "d"), "--workers", "2",
                             "--objects", "wood_bar,steel_bar", "--scenes", "single", "--single-grasps", "60",
                             "--shard-size", "1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    kids: set[int] = set()
    while time.time() < deadline and len(kids) < 2:
        kids = _children(proc.pid)
        time.sleep(0.2)
    assert len(kids) >= 2, "the workers did not start"
    time.sleep(2.0)  # workers busy simulating
    kids = _children(proc.pid)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    deadline = time.time() + 15
    alive = kids
    while time.time() < deadline and alive:
        alive = {k for k in alive if os.path.exists(f"/proc/{k}") and
                 open(f"/proc/{k}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"}
        time.sleep(0.2)
    assert not alive, f"processes outlived the killed driver: {sorted(alive)}"


def _listening_sockets() -> dict[str, tuple[str, int]]:
    """inode -> (address, port) of every TCP socket in LISTEN state (IPv4 and IPv6)."""
    import socket
    from pathlib import Path

    out = {}
    for name, family in (("/proc/net/tcp", socket.AF_INET), ("/proc/net/tcp6", socket.AF_INET6)):
        try:
            lines = Path(name).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if fields[3] != "0A":
                continue
            hex_ip, hex_port = fields[1].split(":")
            raw = bytes.fromhex(hex_ip)
            raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))  # /proc prints host order
            out[fields[9]] = (socket.inet_ntop(family, raw), int(hex_port, 16))
    return out


def _socket_inodes(pids: set[int]) -> set[str]:
    from pathlib import Path

    inodes = set()
    for pid in pids:
        try:
            fds = list(Path(f"/proc/{pid}/fd").iterdir())
        except OSError:
            continue
        for fd in fds:
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    return inodes


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/proc/net/tcp"), reason="reads listening sockets from /proc")
def test_local_ray_listens_on_loopback_only_and_ignores_ray_address(monkeypatch):
    """No server of ours may listen beyond 127.0.0.1: Ray's GCS, raylet and workers included."""
    import time

    ray = pytest.importorskip("ray")
    from aas_gym.experiments.generate import start_ray

    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:1")  # stale: a local run must neither use it nor wait
    assert not ray.is_initialized()
    t0 = time.perf_counter()
    start_ray("local")
    try:
        assert time.perf_counter() - t0 < 60
        ray.get(ray.remote(lambda: 1).remote())  # workers up
        ours = _children(os.getpid()) | {os.getpid()}
        sockets = _listening_sockets()
        bound = [sockets[i] for i in _socket_inodes(ours) if i in sockets]
        assert len(bound) >= 3  # GCS, raylet, workers at least: Ray's sockets were seen
        exposed = [s for s in bound if not (s[0].startswith("127.") or s[0] in ("::1", "::ffff:127.0.0.1"))]
        assert not exposed, f"Ray listens beyond loopback: {exposed}"
    finally:
        ray.shutdown()
    assert os.environ["RAY_ADDRESS"] == "127.0.0.1:1"  # restored for the caller


def test_an_unreachable_ray_address_fails_fast_and_says_so(tmp_path):
    import socket
    import time

    from aas_gym.experiments.config import DatasetConfig
    from aas_gym.experiments.generate import check_ray_reachable, generate_dataset

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.perf_counter()
    with pytest.raises(ConnectionError, match=f"127.0.0.1:{port}"):
        generate_dataset(DatasetConfig(objects=("wood_bar",), scenes=("single",), single_grasps=1), tmp_path / "d",
                         ray_address=f"127.0.0.1:{port}", progress=False)
    assert time.perf_counter() - t0 < 15 and not (tmp_path / "d").exists()
    with pytest.raises(ConnectionError, match="within"):
        check_ray_reachable(f"ray://127.0.0.1:{port}", timeout_s=2)


class _DevicesThatDie:
    """The part of ``real.PyAudioRig`` that ``RealAcousticSensor`` calls, failing as a sound
    device does: ``plan`` holds, per call, ``"start"`` (the stream dies before the
    excitation came back), ``"mid"`` (after) or ``"ok"``."""

    sample_rate_hz = 44100

    def __init__(self, plan):
        self.plan, self.calls = list(plan), 0

    def record(self, excitation, duration_s, *, save_path=None, labels=None):
        import real
        from real.rig import AudioDevice, RigRecording

        what = self.plan[self.calls]
        self.calls += 1
        dev = AudioDevice(0, "default", "ALSA", 1, 1, 44100.0)
        mic = np.concatenate([np.zeros(300), excitation.loop(duration_s + 0.1)]).astype(np.float32)
        rec = RigRecording(input=mic[:, None], mic_channel=0, sample_rate_hz=44100, excitation=excitation,
                           duration_s=duration_s, latency_samples=None if what == "start" else 300,
                           period_lags_samples=[], events=[], input_device=dev, output_device=dev,
                           stream_mode="separate", reported_latency_s={}, started_at="t", complete=what == "ok")
        if what == "ok":
            return rec
        raise real.DeviceLostError("output stream on device 'default' stopped", device="default", recording=rec)


def test_a_device_lost_as_the_stream_starts_is_retried_and_one_lost_mid_recording_is_not():
    import real

    sensor = real.RealAcousticSensor(_DevicesThatDie(["start", "ok"]))
    with pytest.warns(real.RigWarning, match="retry 1 of 2"):
        assert sensor.sense("impulse", 0.5).metadata["source"] == "real"
    rig = _DevicesThatDie(["mid", "ok"])
    with pytest.raises(real.DeviceLostError):
        real.RealAcousticSensor(rig).sense("impulse", 0.5)
    assert rig.calls == 1
    rig = _DevicesThatDie(["start"] * 3)
    with pytest.raises(real.DeviceLostError), pytest.warns(real.RigWarning):
        real.RealAcousticSensor(rig).sense("impulse", 0.5)
    assert rig.calls == 3


def test_a_tampered_or_damaged_modal_cache_entry_is_rebuilt_not_served(tmp_path):
    """Well-formed entries with doubled frequencies, NaN shapes or flipped bytes: the content
    checksum fails, the entry counts as a miss, the model is solved again and rewritten."""
    from sensors import MATERIALS, ModalModel

    def bar():
        return ModalModel.bar(0.2, 0.025, 0.025, MATERIALS["wood"], resolution=0.5, max_frequency_hz=8000.0,
                              cache_dir=tmp_path, progress=False)

    truth = bar().frequencies_hz
    (entry,) = tmp_path.glob("*.npz")
    assert bar().metadata["cache_hit"]
    with np.load(entry) as data:
        arrays = {k: data[k] for k in data.files}
    tampered = [dict(arrays, frequencies_hz=2 * arrays["frequencies_hz"]),
                dict(arrays, mode_shapes=np.full_like(arrays["mode_shapes"], np.nan)),
                {k: v for k, v in arrays.items() if k != "_sha256"}]          # an entry without one
    for bad in tampered:
        np.savez(entry, **bad)
        model = bar()
        assert not model.metadata.get("cache_hit") and np.array_equal(model.frequencies_hz, truth)
        assert bar().metadata["cache_hit"]                                   # rewritten whole
    raw = bytearray(entry.read_bytes())
    raw[len(raw) // 2:len(raw) // 2 + 64] = bytes(64)                        # 64 bytes zeroed
    entry.write_bytes(bytes(raw))
    model = bar()
    assert not model.metadata.get("cache_hit") and np.array_equal(model.frequencies_hz, truth)



def test_a_blocked_portaudio_call_is_given_up_on_in_order_and_cleaned_up_late():
    """Issue 17 item 6, without a sound server: calls run one after another on a daemon
    thread, the caller waits at most its timeout, and what a late call produced is cleaned up."""
    from real import bounded

    assert bounded.wait_until_idle(10) is None
    release, order, cleaned = threading.Event(), [], []

    def blocked():
        release.wait(30)
        order.append("blocked")
        return "late session"

    try:
        assert bounded.call_bounded(blocked, 0.05, "initializing",
                                    on_late_result=lambda r: (cleaned.append(r), order.append("cleaned"))) == (False, None)
        assert bounded.pending() == "initializing"
        # a later call waits behind it, and is given up on too
        assert bounded.call_bounded(lambda: order.append("next"), 0.05, "terminating") == (False, None)
        assert bounded.pending() == "terminating" and bounded.wait_until_idle(0.05) == "terminating"
        assert order == []
    finally:
        release.set()
    assert bounded.wait_until_idle(30) is None
    # the late result is cleaned up (a PortAudio call too) before the next call runs
    assert order == ["blocked", "cleaned", "next"] and cleaned == ["late session"]
    # calls that finish in time return their result or raise their error
    assert bounded.call_bounded(lambda: 42, 30, "listing") == (True, 42)
    with pytest.raises(ZeroDivisionError):
        bounded.call_bounded(lambda: 1 / 0, 30, "listing")


class _StalledPyAudio:
    """A ``pyaudio`` module whose sound server does not answer until ``release`` is set."""

    def __init__(self):
        self.release, self.terminated = threading.Event(), []
        fake = self

        class PyAudio:
            def __init__(self):
                fake.release.wait(30)

            def terminate(self):
                fake.terminated.append(self)

        self.PyAudio = PyAudio


def test_a_sound_server_that_does_not_answer_fails_the_session_instead_of_hanging(monkeypatch):
    import real
    from real import bounded, devices

    fake = _StalledPyAudio()
    monkeypatch.setattr(devices, "pyaudio", fake)
    try:
        with pytest.raises(real.DeviceLostError, match="did not answer within 0.1 s") as info:
            with devices.portaudio_session(0.1):
                pass
        assert info.value.device == "default"
        # while PortAudio is still blocked, the next session says so at once instead of queueing
        with pytest.raises(real.DeviceLostError, match="still initializing"):
            with devices.portaudio_session(0.1):
                pass
    finally:
        fake.release.set()
    assert bounded.wait_until_idle(30) is None
    assert len(fake.terminated) == 1  # the session that came too late is closed


class _DiskThatFills:
    """A raw partial file on a disk with ``room`` bytes left: short writes, then ENOSPC."""

    def __init__(self, fh, room: int):
        self.fh, self.room = fh, room

    def write(self, data) -> int:
        if self.room == 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.fh.name))
        n = self.fh.write(bytes(data[: self.room]))
        self.room -= n
        return n

    def fileno(self) -> int:
        return self.fh.fileno()

    @property
    def closed(self) -> bool:
        return self.fh.closed

    def close(self) -> None:
        self.fh.close()


def test_a_full_disk_keeps_an_exact_prefix_and_recovery_keeps_the_raw_files_until_it_can_write(tmp_path):
    """Issue 17 item 1, without a sound server (the rig's side: test_real_audio). The writer
    never raises, keeps whole frames of exactly the first samples, and says why it stopped;
    recover_partial writes elsewhere on request and removes nothing it has not saved."""
    import real
    import sensors
    from real.partial_files import PartialWriter

    ex = sensors.Excitation.by_name("impulse")
    header = {"channels": 2, "mic_channel": 1, "sample_rate_hz": ex.sample_rate_hz, "excitation": ex.to_dict(),
              "metadata": {"source": "real"}}
    w = PartialWriter(tmp_path / "disk" / "take.npz", header)
    w._fh = _DiskThatFills(w._fh, room=1003)  # 125 frames of 8 bytes and 3 bytes of the next
    blocks = [np.random.default_rng(i).standard_normal((40, 2)).astype(np.float32) for i in range(6)]
    for b in blocks:
        w.append(b)  # never raises
    w.close()
    assert w.error is not None and w.error.errno == errno.ENOSPC and w.frames_written == 125 and w.has_data
    sent = np.concatenate(blocks)
    # nowhere to write the .npz: a clear error, and the raw files stay
    blocked = tmp_path / "a_file"
    blocked.write_text("")
    with pytest.raises(real.StorageError, match="out_dir") as info:
        real.recover_partial(w.raw_path, out_dir=blocked / "sub")
    assert isinstance(info.value, OSError) and info.value.errno is not None
    assert sorted(p.name for p in w.raw_path.parent.iterdir()) == ["take.partial.f32", "take.partial.json"]
    # elsewhere: the exact prefix, whole frames only
    out = real.recover_partial(tmp_path / "disk" / "take.npz", out_dir=tmp_path / "elsewhere")
    assert out == tmp_path / "elsewhere" / "take.partial.npz" and list(w.raw_path.parent.iterdir()) == []
    obs = sensors.AcousticObservation.load(out)
    np.testing.assert_array_equal(obs.waveform, sent[:125, 1])
    assert obs.metadata["partial"] and not obs.metadata["complete"]


@pytest.mark.parametrize("build", [
    lambda M, m: M.bar(0.2, 0.2, 0.001, m),                        # a 200 x 200 x 1 mm plate
    lambda M, m: M.bar(5.0, 0.02, 0.02, m),                        # a 5 m bar
    lambda M, m: M.bar(0.2, 0.02, 0.02, m, resolution=20),
    lambda M, m: M.tube(0.2, 0.01, 0.009999, m),                   # a 1 um tube wall
    lambda M, m: M.rod(0.2, 0.01, m, element_size_m=1e-4),
], ids=["plate", "5 m bar", "resolution 20", "1 um wall", "fine rod"])
def test_hostile_sizes_are_refused_at_once_with_a_way_out(build):
    """Each ran for minutes or exhausted memory; now a MeshError before any meshing."""
    import time

    from sensors import MATERIALS, MeshError, ModalModel

    t0 = time.process_time()
    with pytest.raises(MeshError, match="degrees of freedom.*max_dof="):
        build(ModalModel, MATERIALS["steel"])
    assert time.process_time() - t0 < 5.0   # refused, not attempted (generous on a loaded machine)


@pytest.mark.slow
def test_a_mesh_in_the_wrong_unit_is_refused_suggesting_scale(tmp_path):
    import trimesh

    from sensors import MATERIALS, MeshError, ModalModel

    box_mm = trimesh.creation.box([200.0, 20.0, 20.0])                # millimetres
    with pytest.raises(MeshError, match=r"200 m across.*scale= \(1e-3"):
        ModalModel.from_mesh(box_mm, MATERIALS["steel"], cache_dir=tmp_path, progress=False)
    with pytest.raises(MeshError, match=r"across.*scale="):
        ModalModel.from_mesh(trimesh.creation.box([1e-3, 1e-3, 1e-3]), MATERIALS["steel"], cache_dir=tmp_path)
    sliver = trimesh.creation.box([0.2, 0.02, 1e-5])                  # 10 um thick
    with pytest.raises(MeshError, match="degrees of freedom"):
        ModalModel.from_mesh(sliver, MATERIALS["steel"], scale=1.0, cache_dir=tmp_path, progress=False)
    model = ModalModel.from_mesh(box_mm, MATERIALS["steel"], scale=1e-3, cache_dir=tmp_path, progress=False,
                                 max_frequency_hz=3000.0)
    assert abs(np.ptp(model.nodes_m[:, 0]) - 0.2) < 1e-3
