"""Select AMASS walking clips, resample them to 30 fps and write one compact training file.

    python data/prepare_amass.py AMASS_ROOT data/amass_walking.npz
    python data/prepare_amass.py AMASS_ROOT out.npz --clip-list my_walks.txt --skip-broken
    python data/prepare_amass.py AMASS_ROOT out.npz --include walk stand idle turn

The last form also keeps the standing and transition clips around the walks (file names with
"stand", "idle" or "turn"), which the predictor's training mix needs (docs/predictor.md).

AMASS_ROOT holds the unpacked sub-datasets (CMU/, BMLrub/, KIT/, ...), SMPL+H G
``*_poses.npz`` or SMPL-X ``*_stageii.npz``. The split is by sub-dataset (test: BMLrub;
validation: HumanEva, MPI_HDM05, SFU, MPI_mosh; training: the rest); see
:mod:`gaitnet.motion.amass` for the selection rules and :mod:`gaitnet.motion.prepared` for the
file layout.
"""

from __future__ import annotations

import sys

from tqdm import tqdm

from gaitnet.errors import USER_ERRORS, user_error_message
from gaitnet.motion.amass import DEFAULT_EXCLUDE, DEFAULT_INCLUDE, TARGET_FPS, DatasetSplit
from gaitnet.motion.prepared import prepare_walking_subset
from gaitnet.training.scripts import ScriptParser


def main(argv: list[str] | None = None) -> int:
    parser = ScriptParser(prog="data/prepare_amass.py", description=__doc__.splitlines()[0])
    parser.add_argument("amass_root", help="folder with the AMASS sub-datasets")
    parser.add_argument("out_file", help="prepared .npz to write")
    parser.add_argument(
        "--include", nargs="+", default=list(DEFAULT_INCLUDE), help="file-name keywords to keep"
    )
    parser.add_argument(
        "--exclude", nargs="*", default=list(DEFAULT_EXCLUDE), help="file-name keywords to drop"
    )
    parser.add_argument("--clip-list", help="text file of clip paths relative to AMASS_ROOT")
    parser.add_argument("--fps", type=float, default=TARGET_FPS, help="output frame rate")
    parser.add_argument("--min-frames", type=int, default=20, help="shortest clip kept")
    parser.add_argument("--val", nargs="+", default=list(DatasetSplit().val))
    parser.add_argument("--test", nargs="+", default=list(DatasetSplit().test))
    parser.add_argument(
        "--skip-broken", action="store_true", help="skip unreadable clips instead of stopping"
    )
    try:
        args = parser.parse_args(argv)
        report = prepare_walking_subset(
            args.amass_root,
            args.out_file,
            include=args.include,
            exclude=args.exclude,
            clip_list=args.clip_list,
            split=DatasetSplit(val=tuple(args.val), test=tuple(args.test)),
            fps=args.fps,
            min_frames=args.min_frames,
            on_error="skip" if args.skip_broken else "raise",
            progress=lambda files, total: tqdm(files, total=total, desc="clips", unit="clip"),
        )
    except USER_ERRORS as exc:
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
    for name, reason in report.skipped:
        print(f"skipped {name}: {reason}")
    print(f"wrote {report.out_file} from {report.n_candidates} candidate clips")
    for split in ("train", "val", "test"):
        minutes = report.n_frames[split] / args.fps / 60
        print(f"  {split:5s} {report.n_clips[split]:5d} clips {minutes:8.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
