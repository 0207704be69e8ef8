"""Size, encoding and decoding time of a session's frames as compressed and as stored PNGs.

Reads ``--frames`` colour and depth frames of a session folder (from its middle), encodes each
with :func:`gaitnet.io.images.encode_png` compressed (the fixed row filter and Huffman coding)
and stored (``compress=False``: unfiltered rows in stored deflate blocks, what ``gaitnet
simulate`` writes unless ``output.compress_frames``), checks that OpenCV decodes both to the
same pixels, and prints the mean file size, encoding and decoding (``cv2.imdecode``, what the
session reader uses) milliseconds per frame on one thread, best of ``--repeat`` passes.

    python benchmarks/bench_png.py SESSION [--frames 30] [--repeat 3]
"""

from __future__ import annotations

import os

os.environ["OPENBLAS_NUM_THREADS"] = "1"

import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.io import SessionFolder  # noqa: E402
from gaitnet.io.images import depth_to_units, encode_png  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402


def best_ms(fn, items: list, repeat: int) -> tuple[float, list]:
    """Best mean milliseconds per item of ``fn`` over ``repeat`` passes, and its outputs."""
    best, out = np.inf, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = [fn(x) for x in items]
        best = min(best, (time.perf_counter() - t0) / len(items) * 1e3)
    return best, out


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("session", type=Path, help="a session folder")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    if args.frames < 1 or args.repeat < 1:
        ap.error("--frames and --repeat must be at least 1")
    cv2.setNumThreads(1)
    session = SessionFolder(args.session)
    scale = session.calibration.depth_scale_m
    first = max(0, len(session) // 2 - args.frames // 2)
    frames = [session.frame(k) for k in range(first, min(len(session), first + args.frames))]
    kinds = {
        "colour": [f.rgb for f in frames],
        "depth": [depth_to_units(f.depth_m, scale) for f in frames],
    }
    print(f"{args.session.name}: {len(frames)} frames, ms per frame on one thread")
    for name, images in kinds.items():
        for compress in (True, False):
            enc_ms, data = best_ms(lambda im, c=compress: encode_png(im, c), images, args.repeat)
            buffers = [np.frombuffer(d, np.uint8) for d in data]
            dec_ms, back = best_ms(
                lambda b: cv2.imdecode(b, cv2.IMREAD_UNCHANGED), buffers, args.repeat
            )
            for im, got in zip(images, back, strict=True):
                if not np.array_equal(got[..., ::-1] if got.ndim == 3 else got, im):
                    raise SystemExit(f"{name}: the decoded pixels differ from the encoded ones")
            size_kb = np.mean([len(d) for d in data]) / 1e3
            label = "compressed" if compress else "stored"
            print(
                f"  {name:6s} {label:10s} {size_kb:6.0f} kB  encode {enc_ms:5.2f}  "
                f"decode {dec_ms:5.2f}"
            )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
