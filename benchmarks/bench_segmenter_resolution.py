"""How sharp are the feet when the scores come from a coarse grid?

For each output stride (in frame pixels) the TRUE label maps of a labelled set are averaged over
stride × stride cells (the one-hot labels of the valid pixels, ``avg_pool2d``) and upsampled
back bilinearly, as a net's coarsest score map is, and the arg-max is scored against the
labels: the IoU of the cell-average score map of each grid, a guide to what a net of that
output stride can draw (not a strict bound: a net's scores need not be cell averages). The
committed model's input scale 0.5 makes its output stride 4 a grid of 8 frame pixels.
docs/segmenter.md, *Finer output and calibration*.

    python benchmarks/bench_segmenter_resolution.py data/cache/seg/test/test.txt \
        [--strides 16 8 4 2]
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

try:
    import torch
    from torch.nn import functional as nnf
except ModuleNotFoundError as exc:  # the core install has no PyTorch
    raise SystemExit(f"error: {exc.name} is not installed: pip install -e '.[train]'") from None

from gaitnet.errors import InputError
from gaitnet.evaluation.segmentation import confusion_matrix, segmentation_scores
from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.training.scripts import ScriptParser
from gaitnet.training.segmenter_data import resolve_set, set_name

IGNORE = 255


def ceiling_confusion(labels: np.ndarray, stride: int, num_classes: int) -> np.ndarray:
    """Confusion matrix of the arg-max of ``labels`` (H, W) averaged over ``stride``-pixel cells
    and bilinearly upsampled back, against ``labels`` itself (ignored pixels take no part in the
    averages and are not scored)."""
    valid = labels != IGNORE
    if np.any(labels[valid] >= num_classes):
        raise InputError(f"a label value is ≥ the {num_classes} classes of --classes")
    onehot = nnf.one_hot(torch.from_numpy(np.where(valid, labels, 0).astype(np.int64)), num_classes)
    grid = (onehot * torch.from_numpy(valid)[..., None]).permute(2, 0, 1)[None].float()
    coarse = nnf.avg_pool2d(grid, stride, ceil_mode=True)
    back = nnf.interpolate(coarse, size=labels.shape, mode="bilinear", align_corners=False)
    pred = back.argmax(1)[0].numpy()
    return confusion_matrix(pred, labels, num_classes, ignore_index=IGNORE)


def main(argv: list[str] | None = None) -> int:
    parser = ScriptParser(description=__doc__.splitlines()[0])
    parser.add_argument("sets", nargs="+", help="split files or frame folders")
    parser.add_argument("--strides", type=int, nargs="+", default=[16, 8, 4, 2])
    parser.add_argument("--classes", default="background,foot,leg")
    args = parser.parse_args(argv)
    names = args.classes.split(",")
    if min(args.strides) < 1 or len(names) < 2:
        parser.error("--strides must be ≥ 1 and --classes must name at least 2 classes")
    print(f"{'set':10s} {'stride':>6s} {'mIoU':>7s} " + " ".join(f"{n:>10s}" for n in names))
    for path in args.sets:
        root, ids = resolve_set(Path(path))
        folder = SegmentationFolder(root, ids)
        label_maps = [folder.read_labels(i)[0] for i in folder.ids]
        for stride in args.strides:
            conf = sum(ceiling_confusion(lab, stride, len(names)) for lab in label_maps)
            scores = segmentation_scores(conf, names)
            ious = " ".join(f"{scores['iou'][n]:10.4f}" for n in names)
            print(f"{set_name(Path(path)):10s} {stride:6d} {scores['miou']:7.4f} {ious}")
    return 0


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
