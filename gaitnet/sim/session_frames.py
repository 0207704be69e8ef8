"""The frames of a simulated session: render, expose and sense each one, in worker processes.

Each frame is rendered at its true mid-exposure time, integrated over its exposure time
(motion blur, :mod:`gaitnet.sim.render_motion`), passed through the D455 colour and depth
models, and checked against the foot markers. Frames are independent except through the
auto-exposure, which is modelled as on a real camera: it measures each frame's brightness
(:func:`gaitnet.sim.sensor_model.auto_exposure`), smooths it (a first-order loop, gain
:data:`AE_GAIN` per frame), and the new setting takes effect :data:`AE_LATENCY` frames later
(the sensor applies exposure registers written during frame ``k`` at frame ``k + 2``); the loop
starts converged on the first frame's scene, as a camera that streamed before the recording.
The exposure factor ``E`` of a frame is the loop's value times the session's exposure factor
and its slow drift; the exposure time is ``camera.exposure_time_s(E)``.

Because of that latency, :data:`AE_LATENCY` frames can be rendered at once, each in its own
worker process (``workers``); every frame draws its noise from its own generators (children of
the ``sensor`` and ``depth`` streams, one per frame), so the output is byte-identical whatever
the number of workers and their timing. Worker processes are forked from a ``forkserver``
(:mod:`gaitnet.sim.worker_pool`) that has imported the simulator once (``spawn`` where there
is none), so they start in milliseconds instead of importing it each; as with ``spawn``, a
script that calls :func:`gaitnet.sim.session.simulate_session` with workers must guard its top
level with ``if __name__ == "__main__":``.
"""

from __future__ import annotations

import ctypes
import pickle
import signal
from collections import deque
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.config import SimConfig
from gaitnet.sim.gait import Walk
from gaitnet.sim.scene_setup import SimScene
from gaitnet.sim.sensor_model import apply_sensor, auto_exposure
from gaitnet.sim.worker_pool import (
    AE_LATENCY,
    default_workers,
    interrupts_deferred,
    start_forkserver,
    worker_context,
)

AE_GAIN = 0.25  # share of the measured correction applied per frame


@dataclass(frozen=True, eq=False)
class FrameJob:
    """Everything the frames of one session need (shared by the workers)."""

    cfg: SimConfig
    scene: SimScene
    times: np.ndarray
    T_WfromC: np.ndarray
    drift: np.ndarray
    colour_seeds: list[np.random.SeedSequence]
    depth_seeds: list[np.random.SeedSequence]
    marker_checks: object  # (walk, t, T_WfromC, K, depth, label, instance) -> rows

    @property
    def walk(self) -> Walk:
        return self.scene.walk


@dataclass(frozen=True, eq=False)
class FrameOut:
    """One sensed frame: 8-bit colour, depth [m], labels, its brightness measurement, the
    exposure factor and time it was taken with, and its foot-marker check rows."""

    index: int
    rgb: NDArray[np.uint8]
    depth_m: NDArray[np.float32]
    label: NDArray[np.uint8]
    instance: NDArray[np.uint8]
    ae_target: float
    exposure: float
    exposure_s: float
    marker_rows: list


def make_job(cfg: SimConfig, scene: SimScene, times, T_WfromC, rngs, marker_checks) -> FrameJob:
    """The session's frame job; draws the drift and one seed per frame from the ``sensor``
    and ``depth`` streams."""
    n = len(times)
    sensor_rng = rngs["sensor"]
    drift = np.cumsum(sensor_rng.normal(0.0, cfg.scene.exposure_drift / np.sqrt(n), n))
    colour = np.random.SeedSequence(int(sensor_rng.integers(2**63))).spawn(n)
    depth = np.random.SeedSequence(int(rngs["depth"].integers(2**63))).spawn(n)
    return FrameJob(cfg, scene, np.asarray(times), T_WfromC, drift, colour, depth, marker_checks)


def render_one(job: FrameJob, k: int, exposure: float) -> FrameOut:
    """Frame ``k`` taken with the exposure factor ``exposure``."""
    cam = job.cfg.camera
    K = cam.intrinsics().K
    t = float(job.times[k])
    exposure_s = cam.exposure_time_s(exposure)
    result = job.scene.render(cam, t, job.T_WfromC[k], exposure_s)
    rgb, depth = apply_sensor(
        result,
        K,
        np.random.default_rng(job.colour_seeds[k]),
        job.cfg.sensor,
        exposure,
        np.random.default_rng(job.depth_seeds[k]),
        job.scene.depth_unit,
    )
    rows = job.marker_checks(
        job.walk, t, job.T_WfromC[k], K, result.depth_m, result.label, result.instance
    )
    return FrameOut(
        k, rgb, depth, result.label, result.instance, auto_exposure(result.rgb_linear),
        exposure, exposure_s, rows,
    )  # fmt: skip


# A worker hands a frame's maps back through one of AE_LATENCY shared buffers (frame k: buffer
# k % AE_LATENCY, free again once the main process has copied frame k out, which it does
# before it asks for frame k + AE_LATENCY): ~10× less CPU than sending them through a pipe.
_MAPS = (("depth_m", 1, np.float32), ("rgb", 3, np.uint8), ("label", 1, np.uint8),
         ("instance", 1, np.uint8))  # fmt: skip
_JOB: FrameJob | None = None  # the job of a worker process
_SLOTS: list = []  # and the shared buffers


def _slot_size(cam) -> int:
    return cam.height * cam.width * sum(ch * np.dtype(dt).itemsize for _, ch, dt in _MAPS)


def _slot_maps(buf, cam) -> dict[str, np.ndarray]:
    """The frame maps laid out in one shared buffer (float32 first: aligned)."""
    maps, offset = {}, 0
    for name, ch, dt in _MAPS:
        shape = (cam.height, cam.width, ch)[: 3 if ch > 1 else 2]
        maps[name] = np.frombuffer(buf, dt, int(np.prod(shape)), offset).reshape(shape)
        offset += maps[name].nbytes
    return maps


def _init_worker(job: ctypes.Array, slots: list) -> None:
    global _JOB, _SLOTS
    # Ctrl-C reaches the whole process group: the main process stops the pool (its
    # ``terminate``), so a worker ignores SIGINT rather than print a traceback of its own
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    cv2.setNumThreads(1)
    _JOB, _SLOTS = pickle.loads(memoryview(job).cast("B")), slots


def _work(k: int, exposure: float) -> FrameOut:
    assert _JOB is not None
    out = render_one(_JOB, k, exposure)
    for name, view in _slot_maps(_SLOTS[k % AE_LATENCY], _JOB.cfg.camera).items():
        view[...] = getattr(out, name)
    return replace(out, depth_m=None, rgb=None, label=None, instance=None)  # in the slot


def render_frames(job: FrameJob, workers: int | None = None) -> Iterator[FrameOut]:
    """All frames of ``job`` in order (module docstring).

    ``workers`` > 1 renders up to :data:`AE_LATENCY` frames at once in worker processes
    (:func:`gaitnet.sim.worker_pool.worker_context`; the job is pickled once into shared
    memory that every worker reads), with the same bytes as 1; None:
    :func:`gaitnet.sim.worker_pool.default_workers`.
    """
    n = len(job.times)
    cam = job.cfg.camera
    ae: list[float] = []  # ae[j + 1]: the loop after measuring frame j

    def converged_on_first() -> None:
        first = job.scene.render(cam, float(job.times[0]), job.T_WfromC[0])
        ae.append(auto_exposure(first.rgb_linear))

    gain = job.scene.exposure_gain

    def exposure_of(k: int) -> float:
        return ae[max(0, k + 1 - AE_LATENCY)] * gain * float(np.exp(job.drift[k]))

    def measured(out: FrameOut) -> FrameOut:
        ae.append(ae[-1] + AE_GAIN * (out.ae_target - ae[-1]))
        return out

    workers = default_workers() if workers is None else int(workers)
    if min(workers, AE_LATENCY, n) <= 1:
        converged_on_first()
        for k in range(n):
            yield measured(render_one(job, k, exposure_of(k)))
        return
    ctx = worker_context()
    start_forkserver(ctx)
    slots = [ctx.RawArray("B", _slot_size(cam)) for _ in range(AE_LATENCY)]
    blob = pickle.dumps(job, pickle.HIGHEST_PROTOCOL)  # once, not once per worker,
    shared_job = ctx.RawArray("B", len(blob))  # and shared, not sent through each one's pipe
    memoryview(shared_job).cast("B")[:] = blob
    del blob
    with ExitStack() as stack:
        with interrupts_deferred():
            pool = stack.enter_context(
                ctx.Pool(min(workers, AE_LATENCY), _init_worker, (shared_job, slots))
            )
        converged_on_first()  # while the workers read the job
        pending: deque = deque(
            pool.apply_async(_work, (k, exposure_of(k))) for k in range(min(n, AE_LATENCY))
        )
        for k in range(n):
            maps = _slot_maps(slots[k % AE_LATENCY], cam)
            out = pending.popleft().get()
            out = measured(replace(out, **{name: m.copy() for name, m in maps.items()}))
            if k + AE_LATENCY < n:  # its exposure is known now
                pending.append(
                    pool.apply_async(_work, (k + AE_LATENCY, exposure_of(k + AE_LATENCY)))
                )
            yield out
