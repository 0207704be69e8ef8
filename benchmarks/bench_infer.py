"""``gaitnet infer`` on simulated sessions: accuracy, ablation of the correction, and timing.

For each session folder (``gaitnet simulate`` output, with ``groundtruth/``) the filter and the
segmenter run once (:func:`gaitnet.pipeline.infer.observe`; cached with ``--cache``), then the
reconstruction runs once per correction variant, and ``gaitnet evaluate``'s own code scores the
written result folder (``mpjpe_m``, ``foot_nmate_m``, ``foot_nmate_filled_m``,
``stride_rmse_m``, ``body_ate_m``):

- ``thesis``: eq. 4.8 only (prior, root, feet, free bone lengths), no extension;
- ``+constraints``: + knee hinge, range of motion, fixed thigh / shank lengths;
- ``+robust/contact``: + Cauchy loss on the feet, flat stance feet, contact weighting;
- ``+offset``: + the ankle-to-keypoint offset;
- ``+bridge``: + a second pass with the swing gaps bridged to where the foot is seen again
  (``pipeline.gap_fill: bridge``);
- ``+swing`` (the default config): the second pass with each unseen swing filled by the
  template swing between the filter's stance landmarks (``pipeline.gap_fill: swing``).

``--segmenter oracle`` replaces the network by the session's true label maps (what the
pipeline reaches with a perfect segmenter); otherwise an ONNX file (default: the committed one).

    python benchmarks/bench_infer.py SESSION [SESSION ...] [--segmenter X.onnx|oracle]
        [--cache DIR] [--json OUT.json] [--variants default] [--set KEY=VALUE ...]

``--set KEY=VALUE``: overrides of the ``gaitnet infer`` config every variant starts from (e.g.
``edge_refine.radius_px=0``); the cached observations are kept per segmenter and edge
refinement.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from gaitnet.config import load_config
from gaitnet.evaluation.evaluate import evaluate_result
from gaitnet.io import open_session
from gaitnet.motion.onnx_runtime import OnnxPredictor
from gaitnet.pipeline.config import InferConfig
from gaitnet.pipeline.infer import Observations, default_predictor_path, observe, reconstruct
from gaitnet.pipeline.outputs import write_infer_files
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
from gaitnet.segmentation.segment_session import default_segmenter_path
from gaitnet.training.scripts import ScriptParser


class OracleSegmenter:
    """The session's true label maps, looked up by the frame's RGB."""

    arch = "rgb"
    input_scale = 0.5  # its HHA is not looked at: the cheapest stride

    def __init__(self, session_dir: Path) -> None:
        self.path = Path("oracle")
        self.truth: dict[str, np.ndarray] = {}
        for frame in open_session(session_dir).frames():
            png = session_dir / "groundtruth" / "labels" / f"{frame.t_ns}.png"
            self.truth[self._key(frame.rgb)] = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)

    @staticmethod
    def _key(rgb: np.ndarray) -> str:
        return hashlib.md5(np.ascontiguousarray(rgb).tobytes()).hexdigest()

    def labels(self, rgb: np.ndarray, hha: np.ndarray) -> np.ndarray:
        return self.truth[self._key(rgb)]


DEFAULT = "+swing (default)"


def variants(base: InferConfig) -> dict[str, InferConfig]:
    c = base.correction
    thesis = replace(
        c,
        fixed_lengths=False,
        knee_hinge=False,
        rom_limits=False,
        robust_foot=False,
        contact_weighting=False,
        flat_foot_contact=False,
        marker_offset=False,
    )
    constraints = replace(thesis, fixed_lengths=True, knee_hinge=True, rom_limits=True)
    robust = replace(constraints, robust_foot=True, flat_foot_contact=True, contact_weighting=True)
    one_pass = replace(base, pipeline=replace(base.pipeline, gap_fill="none"))
    bridge = replace(base, pipeline=replace(base.pipeline, gap_fill="bridge"))
    return {
        "thesis": replace(one_pass, correction=thesis),
        "+constraints": replace(one_pass, correction=constraints),
        "+robust/contact": replace(one_pass, correction=robust),
        "+offset": one_pass,
        "+bridge": bridge,
        DEFAULT: base,
    }


def _flat(metrics: dict) -> dict[str, float]:
    out = {}
    for key, value in metrics.items():
        if isinstance(value, dict):
            out.update({f"{key}.{k}": v for k, v in value.items() if isinstance(v, float)})
        elif isinstance(value, float):
            out[key] = value
    return out


def cached_observations(
    session_dir: Path, base: InferConfig, segmenter: str | None, cache: Path | None
) -> Observations:
    """The filter's and the segmenter's observations of a session
    (:func:`gaitnet.pipeline.infer.observe`), from ``cache`` when it holds them (one file per
    session, segmenter and edge refinement) and kept there when computed. ``segmenter``: an
    ONNX file, ``"oracle"`` or None (the committed one)."""
    tag = "oracle" if segmenter == "oracle" else Path(segmenter or "default").stem
    refine = base.edge_refine
    if tag != "oracle" and refine.radius_px:
        tag += f"_refine{refine.radius_px}-{refine.eps:g}-{refine.region}"
    cached = cache / f"{session_dir.name}_{tag}.pkl" if cache else None
    if cached is not None and cached.exists():
        return pickle.loads(cached.read_bytes())
    if segmenter == "oracle":
        model = OracleSegmenter(session_dir)
    else:
        model = OnnxSegmenter(segmenter or default_segmenter_path(), threads=1, edge_refine=refine)
    obs = observe(open_session(session_dir), base, model)
    if cached is not None:
        cached.parent.mkdir(parents=True, exist_ok=True)
        cached.write_bytes(pickle.dumps(obs))
    return obs


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sessions", nargs="+", type=Path)
    ap.add_argument("--segmenter", default=None, help="ONNX file or 'oracle'")
    ap.add_argument("--predictor", default=None)
    ap.add_argument("--cache", type=Path, default=None, help="folder for cached observations")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--variants", choices=("all", "default"), default="all")
    ap.add_argument(
        "--set",
        dest="overrides",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="infer config overrides",
    )
    args = ap.parse_args()
    base = load_config(InferConfig, None, args.overrides)
    runs = variants(base) if args.variants == "all" else {DEFAULT: base}
    predictor = OnnxPredictor(args.predictor or default_predictor_path())
    table: dict[str, dict[str, list[float]]] = {name: {} for name in runs}
    timing: list[dict[str, float]] = []
    for session_dir in args.sessions:
        obs = cached_observations(session_dir, base, args.segmenter, args.cache)
        for name, cfg in runs.items():
            start = time.perf_counter()
            result = reconstruct(obs, cfg, predictor)
            pose_s = time.perf_counter() - start
            with tempfile.TemporaryDirectory() as tmp:
                write_infer_files(result, Path(tmp), {"path": str(session_dir)})
                metrics = _flat(evaluate_result(tmp, session_dir).metrics)
            for key, value in metrics.items():
                table[name].setdefault(key, []).append(value)
            if name == DEFAULT:
                n = len(result.t_s)
                timing.append(
                    {k: 1e3 * v / n for k, v in obs.timings_s.items()} | {"pose": 1e3 * pose_s / n}
                )
            print(
                f"{session_dir.name:24s} {name:18s} MPJPE {100 * metrics['mpjpe_m']:.2f} cm, "
                f"feet NMATE {100 * metrics['foot_nmate_m.left']:.2f} / "
                f"{100 * metrics['foot_nmate_m.right']:.2f} cm, filled "
                f"{100 * metrics.get('foot_nmate_filled_m.left', float('nan')):.2f} / "
                f"{100 * metrics.get('foot_nmate_filled_m.right', float('nan')):.2f} cm",
                flush=True,
            )
    keys = ["mpjpe_m", "foot_nmate_m.left", "foot_nmate_m.right"]
    keys += ["foot_nmate_filled_m.left", "foot_nmate_filled_m.right", "stride_rmse_m.all"]
    print(f"\nmean over {len(args.sessions)} sessions [cm]")
    print(f"{'variant':20s}" + "".join(f"{k:>27s}" for k in keys))
    for name, metrics in table.items():
        cells = [100 * float(np.mean(metrics[k])) if k in metrics else float("nan") for k in keys]
        print(f"{name:20s}" + "".join(f"{c:27.2f}" for c in cells))
    ms = {k: float(np.mean([t[k] for t in timing])) for k in timing[0]}
    print("ms per frame (wall, this run): " + ", ".join(f"{k} {v:.1f}" for k, v in ms.items()))
    if args.json:
        summary = {name: {k: float(np.mean(v)) for k, v in m.items()} for name, m in table.items()}
        args.json.write_text(json.dumps({"variants": summary, "ms_per_frame": ms}, indent=2))


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
