"""Labelled segmentation frames from a ``gaitnet simulate-dataset`` or labelme folder (sec. 4.1.2).

A folder (``data/README.md`` for users' own labelme folders)::

    images/<id>.png|.jpg   8-bit RGB; images/<id>.json beside it: labelme polygons (optional)
    depth/<id>.png         16-bit depth aligned to RGB, units of camera.yaml's depth_scale_m
    labels/<id>.png        label map 0 background, 1 foot, 2 leg, 255 ignore (when no JSON)
    instances/<id>.png     side map 0 none, 1 left, 2 right (optional, when no JSON)
    camera.yaml            width, height, fx, fy, cx, cy [, depth_scale_m: 0.001]
    labels.txt             labelme class list (optional; default __ignore__, _background_,
                           foot, leg)
    frames.csv             id, gravity_cx, gravity_cy, gravity_cz (optional: unit gravity in
                           the camera frame, pointing down; a missing file, row or empty cell =
                           no IMU, HHA uses its no-gravity fallback)
    train.txt, val.txt, test.txt   split files (optional), one frame id per line

Labels come from ``images/<id>.json`` through labelme's own rasteriser
(:func:`gaitnet.io.labelme_io.read_labelme`) when it exists, else from ``labels/<id>.png``.
Sides from the JSON: a shape's ``group_id`` 1 is left and 2 right (what gaitnet writes),
otherwise its ``description`` saying ``left`` or ``right``, otherwise none; they are rasterised
by the same labelme function over the same shapes in the same order, so overlaps resolve as in
the label map. Without JSON, sides come from ``instances/<id>.png`` (all 0 when absent). Sides
are kept only on foot and leg pixels.

HHA (:func:`gaitnet.segmentation.hha.hha_encode`) is computed once per frame and cached in
``hha/<id>.png`` inside the folder (written atomically). The PNG carries a text chunk
``gaitnet-hha`` with a hash of the HHA settings (:meth:`~gaitnet.segmentation.hha.HhaParams.
fingerprint`), the HHA stride (``hha_stride``: the model's, :func:`~gaitnet.segmentation.hha.
hha_stride`), the intrinsics, the frame's gravity and the depth file's bytes: a cache entry
whose hash differs (settings, code version or inputs changed) is recomputed and replaced. A
folder that cannot be written is read without a cache (logged once).

The files are read and checked by :mod:`gaitnet.segmentation.folder_files`. Splits:
``read_split`` / ``write_split`` (text, one id per line, ``#`` comments and blank lines
ignored). A folder without split files gets ``default_split``: each id goes to
train / val / test by a hash of the id alone (80 / 10 / 10 %), so the split is the same on
every machine and adding frames never moves an existing frame to another split.

Every problem with a file is an :class:`~gaitnet.errors.InputError` with one line naming it:
missing or undecodable images, depth or labels, sizes that differ from camera.yaml, label or
side values outside the conventions, a JSON whose ``imagePath`` is not its frame's image, ids
that are not plain file names (``..``, ``/``) or have no image, bad camera.yaml / frames.csv
values.
"""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import torch

from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_save
from gaitnet.io.labelme_io import CLASS_VALUES, read_labelme, read_labels_txt
from gaitnet.segmentation.augment import AugmentParams, Sample, augment_sample
from gaitnet.segmentation.folder_files import (
    LABEL_VALUES,
    SIDE_VALUES,
    check_id,
    check_size,
    check_values,
    find_image,
    labelme_sides,
    list_frames,
    read_camera_yaml,
    read_gravity_csv,
    read_image,
    read_split,
)
from gaitnet.segmentation.hha import HhaParams, hha_encode

log = logging.getLogger(__name__)

__all__ = ["SegmentationFolder"]

HHA_TEXT_KEY = "gaitnet-hha"


def _chw(image: np.ndarray) -> torch.Tensor:
    """(H, W, 3) uint8 (÷ 255) or float32 in [0, 1] → float32 (3, H, W) tensor."""
    t = torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1)))
    return t.float().div_(255.0) if image.dtype == np.uint8 else t.float()


class SegmentationFolder(torch.utils.data.Dataset):
    """Frames of one folder (module docstring) as tensors for the segmenter.

    ``ids``: frame ids, a split file's path (its ids checked against the folder), or None
    (every labelled frame, :func:`list_frames`). ``augment``: training augmentations
    (:mod:`gaitnet.segmentation.augment`) or None. Item ``k`` is a dict: ``rgb`` float32 (3, H,
    W) in [0, 1], ``hha`` float32 (3, H, W) in [0, 1] (HHA / 255), ``label`` int64 (H, W) (255
    ignore), ``side`` int64 (H, W), ``id`` str. ``hha_stride``: HHA of every ``hha_stride``-th
    pixel, repeated (:func:`~gaitnet.segmentation.hha.hha_encode`).

    Augmentation randomness: after :meth:`set_epoch`, item ``k`` draws from a generator seeded
    by ``(seed, epoch, k)`` (the same augmentation in every process, worker and after a resume,
    whatever the loading order). Until then each read draws a fresh seed from torch's random
    generator (in DataLoader workers torch seeds it per worker and epoch), so epochs differ and
    runs repeat under ``torch.manual_seed``, but a resume repeats them only if it restores
    torch's generator states.
    """

    def __init__(
        self,
        root: str | Path,
        ids: Sequence[str] | str | Path | None = None,
        augment: AugmentParams | None = None,
        hha: HhaParams | None = None,
        cache_hha: bool = True,
        seed: int = 0,
        hha_stride: int = 1,
    ) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise InputError(f"{self.root}: data set folder not found")
        if isinstance(ids, (str, Path)):
            self.ids = read_split(ids, self.root)
        elif ids is None:
            self.ids = list_frames(self.root)
        else:
            self.ids = [check_id(i, str(self.root)) for i in ids]
            for frame_id in self.ids:
                if find_image(self.root, frame_id) is None:
                    raise InputError(
                        f"{self.root / 'images'}: no image for frame id {frame_id!r} "
                        "(.png, .jpg or .jpeg)"
                    )
        self.augment = augment
        self.hha_params = hha or HhaParams()
        self.hha_stride = int(hha_stride)
        self.cache_hha = cache_hha
        self.seed = int(seed)
        self.epoch: int | None = None
        self.intrinsics, self.depth_scale_m = read_camera_yaml(self.root / "camera.yaml")
        self.K = self.intrinsics.K
        labels_txt = self.root / "labels.txt"
        self.class_values = read_labels_txt(labels_txt) if labels_txt.exists() else CLASS_VALUES
        frames_csv = self.root / "frames.csv"
        self.gravity = read_gravity_csv(frames_csv) if frames_csv.exists() else {}
        self._cache_warned = False

    def __len__(self) -> int:
        return len(self.ids)

    def set_epoch(self, epoch: int) -> None:
        """Augmentations of epoch ``epoch`` (class docstring)."""
        self.epoch = int(epoch)

    # --- files of one frame

    def image_path(self, frame_id: str) -> Path:
        path = find_image(self.root, frame_id)
        if path is None:
            raise InputError(f"{self.root / 'images'}: no image for frame id {frame_id!r}")
        return path

    def read_rgb(self, frame_id: str) -> np.ndarray:
        path = self.image_path(frame_id)
        bgr = read_image(path, cv2.IMREAD_COLOR, "colour image")
        check_size(path, bgr, self.intrinsics, "colour image")
        return np.ascontiguousarray(bgr[:, :, ::-1])

    def read_depth(self, frame_id: str) -> tuple[np.ndarray, bytes]:
        """Depth [m] (0 invalid) and the PNG's bytes."""
        path = self.root / "depth" / f"{frame_id}.png"
        if not path.is_file():
            raise InputError(f"{path}: depth image not found")
        raw = path.read_bytes()
        image = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise InputError(f"{path}: cannot decode depth image (corrupt or not a PNG)")
        if image.dtype != np.uint16 or image.ndim != 2:
            raise InputError(
                f"{path}: depth must be a single-channel 16-bit PNG, got {image.dtype} "
                f"with {1 if image.ndim == 2 else image.shape[2]} channels"
            )
        check_size(path, image, self.intrinsics, "depth image")
        return image.astype(np.float32) * np.float32(self.depth_scale_m), raw

    def read_labels(self, frame_id: str) -> tuple[np.ndarray, np.ndarray]:
        """(label map, side map), uint8 (module docstring for the sources)."""
        h, w = self.intrinsics.height, self.intrinsics.width
        json_path = self.root / "images" / f"{frame_id}.json"
        if json_path.is_file():
            label, _, image = read_labelme(json_path, self.class_values)
            if image != self.image_path(frame_id).resolve():
                raise InputError(
                    f"{json_path}: imagePath names {image.name}, not the frame's image "
                    f"{self.image_path(frame_id).name}"
                )
            check_size(json_path, label, self.intrinsics, "annotation")
            side = labelme_sides(json_path, h, w)
        else:
            path = self.root / "labels" / f"{frame_id}.png"
            if not path.is_file():
                raise InputError(
                    f"{path}: label map not found (and no labelme JSON {json_path.name})"
                )
            label = read_image(path, cv2.IMREAD_UNCHANGED, "label map")
            if label.dtype != np.uint8 or label.ndim != 2:
                raise InputError(f"{path}: label map must be a single-channel 8-bit PNG")
            check_size(path, label, self.intrinsics, "label map")
            check_values(path, label, LABEL_VALUES, "label map")
            side_path = self.root / "instances" / f"{frame_id}.png"
            if side_path.is_file():
                side = read_image(side_path, cv2.IMREAD_UNCHANGED, "side map")
                if side.dtype != np.uint8 or side.ndim != 2:
                    raise InputError(f"{side_path}: side map must be a single-channel 8-bit PNG")
                check_size(side_path, side, self.intrinsics, "side map")
                check_values(side_path, side, SIDE_VALUES, "side map")
            else:
                side = np.zeros((h, w), np.uint8)
        side = np.where((label == 1) | (label == 2), side, 0).astype(np.uint8)
        return label, side

    def hha_key(self, frame_id: str, depth_png: bytes) -> str:
        """Hash of everything the frame's HHA depends on (module docstring)."""
        g = self.gravity.get(frame_id)
        parts = [
            self.hha_params.fingerprint(),
            f"stride {self.hha_stride}",
            np.round(self.K, 9).tobytes().hex(),
            "none" if g is None else np.round(g, 9).tobytes().hex(),
            repr(self.depth_scale_m),
            hashlib.sha256(depth_png).hexdigest(),
        ]
        return hashlib.sha256("|".join(parts).encode()).hexdigest()[:32]

    def _encode(self, frame_id: str, depth: np.ndarray) -> np.ndarray:
        gravity = self.gravity.get(frame_id)
        return hha_encode(depth, self.K, gravity, self.hha_params, stride=self.hha_stride)

    def read_hha(self, frame_id: str) -> np.ndarray:
        """The frame's HHA (H, W, 3) uint8, from the cache when it is current."""
        depth, raw = self.read_depth(frame_id)
        if not self.cache_hha:
            return self._encode(frame_id, depth)
        from PIL import Image, UnidentifiedImageError
        from PIL.PngImagePlugin import PngInfo

        key = self.hha_key(frame_id, raw)
        path = self.root / "hha" / f"{frame_id}.png"
        if path.is_file():
            try:
                with Image.open(path) as im:
                    if im.info.get(HHA_TEXT_KEY) == key and im.mode == "RGB":
                        hha = np.asarray(im)
                        if hha.shape[:2] == depth.shape:
                            return hha
            except (UnidentifiedImageError, OSError, SyntaxError, ValueError):
                log.info("%s: unreadable HHA cache entry, recomputing", path)
        hha = self._encode(frame_id, depth)
        info = PngInfo()
        info.add_text(HHA_TEXT_KEY, key)
        try:
            atomic_save(
                path,
                lambda tmp: Image.fromarray(hha).save(tmp, "PNG", pnginfo=info, compress_level=1),
            )
        except OSError as exc:
            if not self._cache_warned:
                log.warning("%s: cannot write the HHA cache (%s); not caching", path, exc)
                self._cache_warned = True
        return hha

    def sample(self, frame_id: str) -> Sample:
        """The frame's maps before augmentation (uint8)."""
        rgb = self.read_rgb(frame_id)
        label, side = self.read_labels(frame_id)
        return Sample(rgb, self.read_hha(frame_id), label, side)

    def __getitem__(self, k: int) -> dict:
        frame_id = self.ids[k]
        s = self.sample(frame_id)
        if self.augment is not None:
            if self.epoch is None:
                draw = int(torch.randint(0, 2**62, (1,)).item())
                rng = np.random.default_rng([self.seed, draw, k])
            else:
                rng = np.random.default_rng([self.seed, self.epoch, k])
            s = augment_sample(s, self.augment, rng)
        return {
            "rgb": _chw(s.rgb),
            "hha": _chw(s.hha),
            "label": torch.from_numpy(s.label.astype(np.int64)),
            "side": torch.from_numpy(s.side.astype(np.int64)),
            "id": frame_id,
        }
