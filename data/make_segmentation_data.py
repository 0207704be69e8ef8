"""Simulated segmentation frames for the committed segmenter (docs/segmenter.md).

Renders four folders with ``gaitnet simulate-dataset`` (camera pitch drawn per frame in 55–75°,
``configs/sim/frames-pitch55-75.yaml``), each from its own seed so that no frame of the
validation, test or held-out sets shares a seed with a training frame::

    OUT/train/     --seed 101, 1000 frames, random floor family; train_large.txt lists the frames
                   not on HELD_OUT, train.txt those among the first 300 (the earlier models' set)
    OUT/train2/    --seed 505, 1000 more, random floor family; train2.txt lists the frames not on
                   HELD_OUT (``data.train_extra`` of configs/segmenter/fusion_cpu_s4_xl.yaml)
    OUT/train3/    --seed 606, 1000 more, likewise (configs/segmenter/fusion_cpu_s4_xxl.yaml)
    OUT/val/       --seed 202, random floor family; val.txt   lists the frames not on HELD_OUT
    OUT/test/      --seed 303, random floor family; test.txt  lists the frames not on HELD_OUT
    OUT/heldout/   --seed 404, every frame on the held-out family; heldout.txt lists them all

The held-out floor family (``wood``: planks, the only family with long parallel seams and
wood-grain rings) never appears in training or validation. Split files are text, one frame id
per line (the format of :func:`gaitnet.segmentation.folder_files.read_split`).

    python data/make_segmentation_data.py --out data/cache/seg

reproduces the data of the committed models (3240 frames, about 1 s each on an idle CPU core;
``--sets`` splits the work between processes). Every frame has its own seed from the set's seed
and its index, so the first 300 frames of ``train/`` are those of a 300-frame render.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

CONFIG = "configs/sim/frames-pitch55-75.yaml"
HELD_OUT = "wood"
SMALL_TRAIN = 300  # train.txt: the first 300 frames (the earlier, 12- and 40-epoch models)

#: name, seed, frames to render, floor family (None: random), split file name.
SETS: tuple[tuple[str, int, int, str | None], ...] = (
    ("train", 101, 1000, None),
    ("val", 202, 80, None),
    ("test", 303, 100, None),
    ("heldout", 404, 60, HELD_OUT),
    ("train2", 505, 1000, None),
    ("train3", 606, 1000, None),
)


def gaitnet_exe() -> str:
    """The ``gaitnet`` entry point beside this interpreter (the venv's), else on PATH."""
    exe = Path(sys.executable).with_name("gaitnet")
    return str(exe) if exe.exists() else "gaitnet"


def render(out: Path, name: str, seed: int, n: int, family: str | None, scale: float) -> Path:
    folder = out / name
    n = max(1, round(n * scale))
    if folder.exists():
        print(f"{folder}: exists, kept")
        return folder
    cmd = [
        gaitnet_exe(),
        "simulate-dataset",
        "--config",
        CONFIG,
        "--n",
        str(n),
        "--seed",
        str(seed),
        "--out",
        str(folder),
    ]
    if family is not None:
        cmd.append(f"scene.floor_family={family}")
    print(" ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    return folder


def write_split(folder: Path, name: str, keep_held_out: bool, first: int | None = None) -> int:
    """``name.txt``: the ids of ``frames.csv`` (its first ``first`` rows) on or off HELD_OUT."""
    with (folder / "frames.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))[:first]
    ids = [r["id"] for r in rows if (r["floor_family"] == HELD_OUT) == keep_held_out]
    (folder / f"{name}.txt").write_text("".join(f"{i}\n" for i in ids))
    return len(ids)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("data/cache/seg"))
    parser.add_argument(
        "--scale", type=float, default=1.0, help="multiply every set's frame count (smoke runs)"
    )
    parser.add_argument(
        "--sets",
        nargs="+",
        choices=[s[0] for s in SETS],
        default=[s[0] for s in SETS],
        help="render only these sets (e.g. in two processes)",
    )
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, seed, n, family in SETS:
        if name not in args.sets:
            continue
        folder = render(args.out, name, seed, n, family, args.scale)
        if name == "train":
            kept = write_split(folder, "train_large", keep_held_out=False)
            print(f"{folder / 'train_large.txt'}: {kept} frames")
            first = max(1, round(SMALL_TRAIN * args.scale))
            kept = write_split(folder, name, keep_held_out=False, first=first)
        else:
            kept = write_split(folder, name, keep_held_out=family == HELD_OUT)
        print(f"{folder / (name + '.txt')}: {kept} frames")
    return 0


if __name__ == "__main__":
    sys.exit(main())
