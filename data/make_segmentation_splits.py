"""Split files for a segmentation folder (a labelme folder or ``gaitnet simulate-dataset`` output).

Writes ``train.txt``, ``val.txt`` and ``test.txt`` into FOLDER (one frame id per line): every
labelled frame (an image with a labelme JSON or a label PNG) goes to a split by a hash of its
id alone (:func:`gaitnet.segmentation.folder_files.default_split`, 80 / 10 / 10 % by default), so
the result is the same on every machine and frames added later never move existing ones.
Existing split files are kept unless ``--overwrite``. ``--check`` then reads every frame once
(images, depth, labels, sides, camera.yaml, frames.csv) and fills the HHA cache
(``FOLDER/hha/``), so a broken file shows up now, as one line naming it, not mid-training.

    python data/make_segmentation_splits.py FOLDER [--fractions 0.8 0.1 0.1] [--check]
"""

from __future__ import annotations

import sys
from pathlib import Path

from tqdm import tqdm

from gaitnet.errors import USER_ERRORS, InputError, user_error_message
from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.segmentation.folder_files import (
    default_split,
    list_frames,
    write_split,
)
from gaitnet.training.scripts import ScriptParser

NAMES = ("train", "val", "test")


def main(argv: list[str] | None = None) -> int:
    parser = ScriptParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="the segmentation data set folder")
    parser.add_argument(
        "--fractions",
        type=float,
        nargs=3,
        default=(0.8, 0.1, 0.1),
        metavar=("TRAIN", "VAL", "TEST"),
        help="shares of the three splits",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing split files")
    parser.add_argument("--check", action="store_true", help="read every frame, fill the HHA cache")
    args = parser.parse_args(argv)
    try:
        if any(not 0 <= f <= 1 for f in args.fractions):
            raise InputError(f"--fractions must be within [0, 1], got {args.fractions}")
        ids = list_frames(args.folder)
        if not ids:
            raise InputError(
                f"{args.folder}: no labelled frame (images/<id>.png with a JSON or labels/<id>.png)"
            )
        paths = {name: args.folder / f"{name}.txt" for name in NAMES}
        existing = [p.name for p in paths.values() if p.exists()]
        if existing and not args.overwrite:
            print(f"{args.folder}: keeping the existing {', '.join(existing)} (--overwrite)")
        else:
            split = default_split(ids, dict(zip(NAMES, args.fractions, strict=True)))
            for name, path in paths.items():
                write_split(path, split[name])
                print(f"{path}: {len(split[name])} frames")
        if args.check:
            ds = SegmentationFolder(args.folder, ids)
            for k in tqdm(range(len(ds)), desc="checking", unit="frame"):
                ds.sample(ds.ids[k])
            print(f"{args.folder}: {len(ds)} frames read, HHA cached in {args.folder / 'hha'}")
    except USER_ERRORS as exc:
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
