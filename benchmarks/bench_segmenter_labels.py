"""The segmenter's label maps before and after the foot post-processing, on labelled sets.

For every frame of each labelled set (a folder of ``gaitnet simulate-dataset`` output or a labelme
folder, or a split file of one, as ``eval.sets`` takes them):
the network's arg-max labels from the set's RGB and HHA (read as training and
``train/segmenter.py --eval-only`` read them, so the "network" row repeats the model card), the
edge refinement of ``gaitnet segment`` and ``gaitnet infer`` (``refined``: the boundaries moved
to the frame's colour edges, :mod:`gaitnet.segmentation.edge_refine`; ``--refine-radius 0``:
none), then their foot post-processing (sec. 4.1.4:
:func:`~gaitnet.segmentation.postprocess.foot_keypoints` with the floor fitted under the set's
gravity, :func:`~gaitnet.segmentation.postprocess.kept_feet_labels`): foot pixels less than
``min_foot_height_m`` above the floor, and blobs that fail the depth checks, become background.
Both are scored by ``gaitnet evaluate``'s own code
(:func:`~gaitnet.evaluation.label_maps.evaluate_label_maps`).

    python benchmarks/bench_segmenter_labels.py SET [SET ...] [--model X.onnx]
        [--min-foot-height 0.01] [--flip-average] [--refine-radius 6] [--refine-eps 3e-4]
        [--refine-region feet] [--json OUT.json]
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from gaitnet.evaluation.label_maps import evaluate_label_maps
from gaitnet.io.images import encode_png
from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.segmentation.edge_refine import EdgeRefineParams, argmax_classes, refine_labels
from gaitnet.segmentation.hha import HhaParams, find_floor, hha_stride
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter, network_input
from gaitnet.segmentation.postprocess import FootKeypointParams, foot_keypoints, kept_feet_labels
from gaitnet.segmentation.segment_session import default_segmenter_path
from gaitnet.training.scripts import ScriptParser
from gaitnet.training.segmenter_data import resolve_set, set_name


def score_set(
    root: Path, net: OnnxSegmenter, params: FootKeypointParams, refine: EdgeRefineParams
) -> dict[str, dict[str, object]]:
    """``network``, ``refined`` (with ``refine.radius_px`` > 0) and ``post-processed`` scores
    of one labelled set (a folder or a split file, as ``eval.sets`` takes them)."""
    folder_root, ids = resolve_set(root)
    ds = SegmentationFolder(folder_root, ids, hha_stride=hha_stride(net.input_scale))
    names = (
        ("network", "refined", "post-processed")
        if refine.radius_px
        else ("network", "post-processed")
    )
    with tempfile.TemporaryDirectory() as tmp:
        out = {name: Path(tmp) / name / "labels" for name in names}
        for folder in out.values():
            folder.mkdir(parents=True)
        for frame_id in ds.ids:
            rgb, hha = ds.read_rgb(frame_id), ds.read_hha(frame_id)
            depth, _ = ds.read_depth(frame_id)
            logits = net(network_input(net.arch, rgb, hha))
            labels = {"network": argmax_classes(logits)[0]}
            if refine.radius_px:
                labels["refined"] = refine_labels(logits[0], rgb, labels["network"], refine)
            chosen = labels.get("refined", labels["network"])
            gravity = ds.gravity.get(frame_id)
            up = None if gravity is None else -np.asarray(gravity)
            plane = find_floor(depth, ds.K, up, HhaParams())
            feet = foot_keypoints(chosen, depth, ds.K, params, gravity_C=gravity, plane=plane)
            labels["post-processed"] = kept_feet_labels(chosen, feet)
            for name, label_map in labels.items():
                (out[name] / f"{frame_id}.png").write_bytes(encode_png(label_map))
        return {
            name: {**evaluate_label_maps(folder, folder_root)[0], "frames": len(ds.ids)}
            for name, folder in out.items()
        }


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sets", nargs="+", type=Path, help="labelled set folders or split files")
    ap.add_argument("--model", type=Path, default=None, help="segmenter (default: committed)")
    ap.add_argument(
        "--min-foot-height",
        type=float,
        default=FootKeypointParams().min_foot_height_m,
        help="feet.min_foot_height_m [m]",
    )
    ap.add_argument(
        "--flip-average",
        action="store_true",
        help="average the logits over each frame and its mirror image (gaitnet segment "
        "--flip-average)",
    )
    default = EdgeRefineParams()
    ap.add_argument(
        "--refine-radius",
        type=int,
        default=default.radius_px,
        help="edge refinement radius [px] (gaitnet segment --refine-radius; 0: none)",
    )
    ap.add_argument("--refine-eps", type=float, default=default.eps, help="its regularisation")
    ap.add_argument("--refine-region", choices=("feet", "frame"), default=default.region)
    ap.add_argument("--json", type=Path, default=None, help="also write the scores here")
    args = ap.parse_args()
    net = OnnxSegmenter(
        args.model or default_segmenter_path(), threads=1, flip_average=args.flip_average
    )
    params = replace(FootKeypointParams(), min_foot_height_m=args.min_foot_height)
    try:
        refine = EdgeRefineParams(args.refine_radius, args.refine_eps, args.refine_region)
    except ValueError as exc:
        ap.error(f"--refine-radius / --refine-eps: {exc}")
    print(
        f"model {net.path}; min_foot_height_m {params.min_foot_height_m}; "
        f"flip_average {net.flip_average}; edge refinement {refine}"
    )
    print(f"{'set':10s} {'labels':15s} {'frames':>6s} {'pix acc':>8s} {'mIoU':>7s} "
          f"{'FW-IoU':>7s} {'bg':>7s} {'foot':>7s} {'leg':>7s}")  # fmt: skip
    results = {}
    for root in args.sets:
        results[set_name(root)] = score_set(root, net, params, refine)
        for name, s in results[set_name(root)].items():
            iou = s["iou"]
            print(f"{set_name(root):10s} {name:15s} {s['frames']:6d} {s['pixel_acc']:8.4f} "
                  f"{s['miou']:7.4f} {s['fw_iou']:7.4f} {iou['background']:7.4f} "
                  f"{iou['foot']:7.4f} {iou['leg']:7.4f}")  # fmt: skip
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
