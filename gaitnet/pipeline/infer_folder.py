"""``gaitnet infer`` from an open session to a result folder: the two networks, the run and the
staged writing of every file (:mod:`gaitnet.pipeline.outputs`), shared by ``gaitnet infer`` and
``gaitnet batch`` so that both write the same folder.

The folder appears only when complete: every file is written into a hidden staging folder that
is renamed into place at the end (:class:`gaitnet.io.atomic.StagedFolder`); an error or an
interrupt removes the staging folder and leaves the target as it was.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gaitnet.config import dump_config
from gaitnet.io.atomic import StagedFolder
from gaitnet.io.images import encode_png
from gaitnet.io.types import SessionSource
from gaitnet.pipeline.config import InferConfig
from gaitnet.pipeline.infer import InferResult, Progress, default_predictor_path, run_infer
from gaitnet.pipeline.outputs import write_infer_files

if TYPE_CHECKING:
    from gaitnet.motion.onnx_runtime import OnnxPredictor
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter

__all__ = ["InferModels", "InferRun", "load_models", "write_infer_folder"]


@dataclass
class InferModels:
    """The two networks of a run, loaded once and reusable for many sessions."""

    segmenter: OnnxSegmenter
    predictor: OnnxPredictor


@dataclass
class InferRun:
    """A written result folder: its ``path``, the ``result``, the gait summary ``gait`` (as in
    ``summary.json``) and the wall-clock seconds of the pipeline (``wall_s``)."""

    path: Path
    result: InferResult
    gait: dict
    wall_s: float


def load_models(
    cfg: InferConfig, segmenter: str | Path | None = None, predictor: str | Path | None = None
) -> InferModels:
    """The segmenter and the motion predictor of ``cfg.models`` (``segmenter`` / ``predictor``
    given here first, then the config's files, else the committed small models), each with
    ``models.threads`` onnxruntime threads."""
    # imported here: onnxruntime loads only once the arguments are known to be good
    from gaitnet.motion.onnx_runtime import OnnxPredictor
    from gaitnet.segmentation import onnx_runtime
    from gaitnet.segmentation.segment_session import default_segmenter_path

    threads = cfg.models.threads
    return InferModels(
        segmenter=onnx_runtime.OnnxSegmenter(
            segmenter or cfg.models.segmenter or default_segmenter_path(),
            threads=threads,
            flip_average=cfg.models.segmenter_flip_average,
            edge_refine=cfg.edge_refine,
        ),
        predictor=OnnxPredictor(
            predictor or cfg.models.predictor or default_predictor_path(), threads=threads
        ),
    )


def write_infer_folder(
    session: SessionSource,
    cfg: InferConfig,
    models: InferModels,
    out: str | Path,
    facts: dict[str, object],
    *,
    overwrite: bool = False,
    save_labels: bool = False,
    progress: Callable[[str], Progress] | None = None,
) -> InferRun:
    """Run the pipeline on ``session`` and write the result folder ``out`` (module docstring;
    the files of :mod:`gaitnet.pipeline.outputs`, ``infer_config.yaml`` and with
    ``save_labels`` every frame's label map in ``labels/``). ``facts``: ``path`` and
    ``software`` for ``summary.json`` and the report (the device and the frame count are added
    here); ``progress(stage)`` as in :func:`gaitnet.pipeline.infer.run_infer`."""
    stage = StagedFolder(out, overwrite)
    try:
        if save_labels:
            (stage.path / "labels").mkdir()

        def keep(t_ns: int, labels: np.ndarray) -> None:
            (stage.path / "labels" / f"{t_ns}.png").write_bytes(encode_png(labels))

        start = time.perf_counter()
        result = run_infer(
            session,
            cfg,
            models.segmenter,
            models.predictor,
            progress=progress,
            keep_labels=keep if save_labels else None,
        )
        wall = time.perf_counter() - start
        all_facts = {
            "path": facts.get("path", ""),
            "device": session.calibration.device,
            "frames_in_session": len(session),
            "software": facts.get("software", ""),
        }
        gait = write_infer_files(result, stage.path, all_facts)
        (stage.path / "infer_config.yaml").write_text(dump_config(cfg))
        path = stage.commit()
    except BaseException:
        stage.abort()
        raise
    return InferRun(path, result, gait, wall)
