"""SegmentationFolder, split files and augmentations: round trips, known label maps, alignment."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import yaml

from gaitnet.config import load_config
from gaitnet.errors import InputError
from gaitnet.io.images import encode_png
from gaitnet.io.labelme_io import labels_txt, read_labelme
from gaitnet.segmentation import dataset as dataset_module
from gaitnet.segmentation.augment import AugmentParams, Sample, augment_sample, flip_sides
from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.segmentation.folder_files import (
    default_split,
    list_frames,
    read_split,
    write_split,
)
from gaitnet.segmentation.hha import HhaParams, hha_encode
from gaitnet.sim.config import SimConfig
from gaitnet.sim.dataset import simulate_dataset

ROOT = Path(__file__).parents[1]
W, H = 64, 48
NO_AUG = AugmentParams(
    hflip_prob=0, scale_min=1, scale_max=1, brightness=0, contrast=0, saturation=0
)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> Path:
    """3 simulated 160×120 frames with labelme JSON (configs/sim/tiny.yaml)."""
    cfg = load_config(
        SimConfig, ROOT / "configs" / "sim" / "tiny.yaml", ["output.preview_frames=0"]
    )
    out = tmp_path_factory.mktemp("seg") / "sim"
    return simulate_dataset(cfg, 3, seed=3, out_dir=out, labelme=True).path


def copy_of(src: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "copy"
    shutil.copytree(src, dst)
    shutil.rmtree(dst / "hha", ignore_errors=True)
    return dst


def handmade(root: Path) -> tuple[np.ndarray, np.ndarray]:
    """A 64×48 one-frame labelme folder 'a' of rectangles; returns the expected label and side
    maps (a labelme rectangle [[x1, y1], [x2, y2]] covers rows y1..y2, columns x1..x2)."""
    for sub in ("images", "depth"):
        (root / sub).mkdir(parents=True)
    rng = np.random.default_rng(0)
    (root / "images" / "a.png").write_bytes(encode_png(rng.integers(0, 256, (H, W, 3), np.uint8)))
    depth = np.full((H, W), 1500, np.uint16)
    depth[30:, :] = 900
    (root / "depth" / "a.png").write_bytes(encode_png(depth))
    shapes = [  # legs first, feet over them; sides by group_id, by description, or none
        ("leg", [[5, 2], [15, 30]], 1, ""),
        ("foot", [[4, 25], [18, 40]], 1, ""),
        ("leg", [[40, 0], [50, 20]], None, "right leg"),
        ("foot", [[38, 18], [55, 33]], None, "Right"),
        ("foot", [[25, 42], [30, 46]], None, ""),
        ("__ignore__", [[0, 44], [3, 47]], None, ""),
    ]
    label = np.zeros((H, W), np.uint8)
    side = np.zeros((H, W), np.uint8)
    values = {"leg": 2, "foot": 1, "__ignore__": 255}
    sides = {1: 1, None: 0}
    doc_shapes = []
    for name, ((x1, y1), (x2, y2)), group, text in shapes:
        label[y1 : y2 + 1, x1 : x2 + 1] = values[name]
        s = sides[group] if group is not None else (2 if "right" in text.lower() else 0)
        side[y1 : y2 + 1, x1 : x2 + 1] = s
        doc_shapes.append(
            {
                "label": name,
                "points": [[x1, y1], [x2, y2]],
                "group_id": group,
                "description": text,
                "shape_type": "rectangle",
                "flags": {},
            }
        )
    doc = {
        "version": "5.5.0",
        "flags": {},
        "shapes": doc_shapes,
        "imagePath": "a.png",
        "imageData": None,
        "imageHeight": H,
        "imageWidth": W,
    }
    (root / "images" / "a.json").write_text(json.dumps(doc))
    (root / "labels.txt").write_text(labels_txt())
    camera = {"width": W, "height": H, "fx": 40.0, "fy": 40.0, "cx": 31.5, "cy": 23.5}
    (root / "camera.yaml").write_text(yaml.safe_dump(camera))
    side[(label != 1) & (label != 2)] = 0
    return label, side


# ----------------------------------------------------------------------------- reading


def test_labels_from_labelme_json_equal_the_hand_drawn_map(tmp_path: Path) -> None:
    label, side = handmade(tmp_path)
    ds = SegmentationFolder(tmp_path)
    assert ds.ids == ["a"] and ds.gravity == {}  # no frames.csv: no IMU
    item = ds[0]
    assert np.array_equal(item["label"].numpy(), label)
    assert np.array_equal(item["side"].numpy(), side)
    assert set(np.unique(side)) == {0, 1, 2}
    rgb = cv2.imread(str(tmp_path / "images" / "a.png"))[:, :, ::-1]
    assert np.allclose(item["rgb"].numpy().transpose(1, 2, 0) * 255, rgb, atol=1e-3)
    depth = np.where(np.arange(H)[:, None] >= 30, 0.9, 1.5) * np.ones((1, W), np.float32)
    expected = hha_encode(depth.astype(np.float32), ds.K, None)
    assert np.allclose(item["hha"].numpy().transpose(1, 2, 0) * 255, expected, atol=1e-3)


def test_simulated_folder_round_trip(simulated: Path, tmp_path: Path) -> None:
    root = copy_of(simulated, tmp_path)
    ds = SegmentationFolder(root)
    assert ds.ids == ["000000", "000001", "000002"] == list_frames(root)
    for k, frame_id in enumerate(ds.ids):
        item = ds[k]
        assert item["id"] == frame_id
        assert item["rgb"].shape == (3, 120, 160) and item["label"].dtype.is_floating_point is False
        label, side = item["label"].numpy(), item["side"].numpy()
        cls, _, _ = read_labelme(root / "images" / f"{frame_id}.json")
        assert np.array_equal(label, cls)  # read through labelme's rasteriser
        truth = cv2.imread(str(root / "labels" / f"{frame_id}.png"), cv2.IMREAD_UNCHANGED)
        inst = cv2.imread(str(root / "instances" / f"{frame_id}.png"), cv2.IMREAD_UNCHANGED)
        for value in (1, 2):  # polygons approximate the rendered masks
            a, b = label == value, truth == value
            if b.sum() > 100:
                assert (a & b).sum() / (a | b).sum() > 0.85
        both = (label > 0) & (label == truth)
        assert (side[both] == inst[both]).mean() > 0.97  # group_id 1/2 → left/right
        depth = cv2.imread(str(root / "depth" / f"{frame_id}.png"), cv2.IMREAD_UNCHANGED)
        expected = hha_encode(depth.astype(np.float32) * 0.001, ds.K, ds.gravity[frame_id])
        assert np.array_equal(np.round(item["hha"].numpy().transpose(1, 2, 0) * 255), expected)
        assert (root / "hha" / f"{frame_id}.png").is_file()
    # without the JSON files the label PNGs and instance maps are read as they are
    for path in (root / "images").glob("*.json"):
        path.unlink()
    item = SegmentationFolder(root)[1]
    truth = cv2.imread(str(root / "labels" / "000001.png"), cv2.IMREAD_UNCHANGED)
    inst = cv2.imread(str(root / "instances" / "000001.png"), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(item["label"].numpy(), truth)
    assert np.array_equal(item["side"].numpy(), inst)


def test_hha_cache_is_used_and_refreshed_when_stale(
    simulated: Path, tmp_path: Path, monkeypatch
) -> None:
    root = copy_of(simulated, tmp_path)
    first = SegmentationFolder(root, ["000000"])[0]["hha"]
    cached = root / "hha" / "000000.png"
    before = cached.read_bytes()

    def refuse(*args, **kwargs):
        raise AssertionError("HHA recomputed although the cache is current")

    monkeypatch.setattr(dataset_module, "hha_encode", refuse)
    again = SegmentationFolder(root, ["000000"])[0]["hha"]
    assert np.array_equal(first.numpy(), again.numpy())
    monkeypatch.undo()
    # other settings → recomputed and replaced
    params = HhaParams(max_height_m=0.6)
    other = SegmentationFolder(root, ["000000"], hha=params)[0]["hha"]
    assert not np.array_equal(first.numpy(), other.numpy())
    assert cached.read_bytes() != before
    # changed depth → recomputed
    depth = cv2.imread(str(root / "depth" / "000000.png"), cv2.IMREAD_UNCHANGED)
    (root / "depth" / "000000.png").write_bytes(encode_png((depth * 0.9).astype(np.uint16)))
    changed = SegmentationFolder(root, ["000000"], hha=params)[0]["hha"].numpy()
    assert not np.array_equal(changed, other.numpy())
    # another HHA stride → recomputed: the strided encoding of the same depth
    strided = SegmentationFolder(root, ["000000"], hha=params, hha_stride=2)
    halved = strided[0]["hha"].numpy()
    depth_m, _ = strided.read_depth("000000")
    expected = hha_encode(depth_m, strided.K, strided.gravity.get("000000"), params, stride=2)
    assert np.array_equal(halved, torch.from_numpy(np.moveaxis(expected, 2, 0)).float() / 255.0)
    assert not np.array_equal(halved, changed)
    assert np.array_equal(SegmentationFolder(root, ["000000"], hha=params)[0]["hha"], changed)
    # a garbage cache file is replaced
    cached.write_bytes(b"not a png")
    assert np.array_equal(SegmentationFolder(root, ["000000"], hha=params)[0]["hha"], changed)
    # cache_hha=False writes nothing
    shutil.rmtree(root / "hha")
    SegmentationFolder(root, ["000001"], cache_hha=False)[0]
    assert not (root / "hha").exists()


# ------------------------------------------------------------------------------ splits


def test_split_files_round_trip_and_default_split(tmp_path: Path) -> None:
    write_split(tmp_path / "train.txt", ["b", "a_1", "c-2.x"])
    (tmp_path / "val.txt").write_text("# validation\n\nd  # a comment\n")
    assert read_split(tmp_path / "train.txt") == ["b", "a_1", "c-2.x"]
    assert read_split(tmp_path / "val.txt") == ["d"]
    ids = [f"{i:06d}" for i in range(2000)]
    split = default_split(ids)
    assert sorted(sum(split.values(), [])) == ids
    for name, share in (("train", 0.8), ("val", 0.1), ("test", 0.1)):
        assert abs(len(split[name]) / len(ids) - share) < 0.03
    more = default_split(ids + [f"x{i}" for i in range(500)])  # adding frames moves none
    for name in split:
        assert [i for i in more[name] if not i.startswith("x")] == split[name]
    assert default_split(ids) == split


def test_split_file_with_unknown_or_escaping_id(tmp_path: Path) -> None:
    handmade(tmp_path)
    (tmp_path / "train.txt").write_text("a\nzz\n")
    with pytest.raises(InputError, match=r"train\.txt: unknown frame id 'zz'"):
        SegmentationFolder(tmp_path, tmp_path / "train.txt")
    (tmp_path / "val.txt").write_text("a\n../../etc/passwd\n")
    with pytest.raises(InputError, match=r"val\.txt:2: .*not a plain file name"):
        read_split(tmp_path / "val.txt")
    with pytest.raises(InputError, match="not a plain file name"):
        SegmentationFolder(tmp_path, ["../a"])
    (tmp_path / "dup.txt").write_text("a\na\n")
    with pytest.raises(InputError, match="listed twice"):
        read_split(tmp_path / "dup.txt")
    assert SegmentationFolder(tmp_path, ["a"]).ids == ["a"]


# -------------------------------------------------------------------------- bad inputs


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda r: (r / "depth" / "a.png").unlink(), r"depth/a\.png: depth image not found"),
        (lambda r: (r / "depth" / "a.png").write_bytes(encode_png(np.ones((10, 10), np.uint16))),
         r"depth/a\.png: depth image is 10×10, expected 64×48"),
        (lambda r: (r / "depth" / "a.png").write_bytes(encode_png(np.ones((H, W), np.uint8))),
         r"depth/a\.png: depth must be a single-channel 16-bit PNG"),
        (lambda r: (r / "depth" / "a.png").write_bytes(b"garbage"),
         r"depth/a\.png: cannot decode"),
        (lambda r: (r / "images" / "a.png").write_bytes(encode_png(np.zeros((H, 10, 3), np.uint8))),
         r"images/a\.png: colour image is 10×48, expected 64×48"),
        (lambda r: (r / "images" / "a.json").write_text("{"), r"a\.json: not valid JSON"),
        (lambda r: (r / "images" / "a.json").write_text(
            (r / "images" / "a.json").read_text().replace('"a.png"', '"../../x.png"')),
         r"a\.json: imagePath '\.\./\.\./x\.png' escapes"),
        (lambda r: (r / "images" / "a.json").unlink(), r"labels/a\.png: label map not found"),
    ],
)  # fmt: skip
def test_bad_frame_files_give_one_line_errors(tmp_path: Path, damage, message: str) -> None:
    handmade(tmp_path)
    damage(tmp_path)
    with pytest.raises(InputError, match=message) as info:
        ds = SegmentationFolder(tmp_path, ["a"])
        ds[0]
    assert "\n" not in str(info.value)


def test_bad_label_maps_camera_and_gravity(tmp_path: Path) -> None:
    handmade(tmp_path)
    (tmp_path / "images" / "a.json").unlink()
    (tmp_path / "labels").mkdir()
    bad = np.zeros((H, W), np.uint8)
    bad[0, 0] = 7
    (tmp_path / "labels" / "a.png").write_bytes(encode_png(bad))
    with pytest.raises(InputError, match=r"labels/a\.png: label map has values \[7\]"):
        SegmentationFolder(tmp_path)[0]
    (tmp_path / "labels" / "a.png").write_bytes(encode_png(np.zeros((H, W), np.uint8)))
    (tmp_path / "instances").mkdir()
    (tmp_path / "instances" / "a.png").write_bytes(encode_png(np.full((H, W), 3, np.uint8)))
    with pytest.raises(InputError, match=r"instances/a\.png: side map has values \[3\]"):
        SegmentationFolder(tmp_path)[0]
    (tmp_path / "frames.csv").write_text("id,gravity_cx,gravity_cy,gravity_cz\na,0,x,1\n")
    with pytest.raises(InputError, match=r"frames\.csv:2: gravity"):
        SegmentationFolder(tmp_path)
    (tmp_path / "frames.csv").write_text("id,gravity_cx,gravity_cy,gravity_cz\na,0,0.6,0.8\nb,,,\n")
    (tmp_path / "instances" / "a.png").unlink()
    ds = SegmentationFolder(tmp_path)
    assert np.allclose(ds.gravity["a"], [0, 0.6, 0.8]) and ds.gravity["b"] is None
    (tmp_path / "camera.yaml").write_text("width: 64\nheight: 48\nfx: 40\n")
    with pytest.raises(InputError, match=r"camera\.yaml: missing key"):
        SegmentationFolder(tmp_path)
    (tmp_path / "camera.yaml").unlink()
    with pytest.raises(InputError, match=r"camera\.yaml: cannot read"):
        SegmentationFolder(tmp_path)
    with pytest.raises(InputError, match="no images/ folder"):
        SegmentationFolder(tmp_path / "labels")


# --------------------------------------------------------------------------- augmentation


def pattern_sample(seed: int = 0) -> Sample:
    """Blobs whose class, side and HHA agree by construction: HHA channel 0 codes the class,
    channel 1 the side, RGB is one colour per class."""
    rng = np.random.default_rng(seed)
    label = np.zeros((60, 80), np.uint8)
    side = np.zeros_like(label)
    for _ in range(6):
        c, s = int(rng.integers(1, 3)), int(rng.integers(1, 3))
        cx, cy = int(rng.integers(10, 70)), int(rng.integers(10, 50))
        cv2.circle(label, (cx, cy), int(rng.integers(4, 10)), c, -1)
        cv2.circle(side, (cx, cy), int(rng.integers(4, 10)), s, -1)
    side[label == 0] = 0
    colours = np.array([[20, 20, 20], [200, 30, 30], [30, 200, 30]], np.uint8)
    hha = np.stack([label * 50 + 1, side * 60 + 1, np.full_like(label, 9)], axis=-1)
    return Sample(colours[label], hha.astype(np.uint8), label, side)


def test_flip_swaps_sides_and_keeps_alignment() -> None:
    s = pattern_sample()
    out = augment_sample(
        s,
        AugmentParams(
            hflip_prob=1.0, scale_min=1, scale_max=1, brightness=0, contrast=0, saturation=0
        ),
        np.random.default_rng(0),
    )
    assert np.array_equal(out.label, s.label[:, ::-1])
    assert np.array_equal(out.hha, s.hha[:, ::-1])
    assert np.allclose(out.rgb * 255, s.rgb[:, ::-1], atol=1e-3)
    expected = s.side[:, ::-1].copy()
    expected[s.side[:, ::-1] == 1], expected[s.side[:, ::-1] == 2] = 2, 1
    assert np.array_equal(out.side, expected)
    assert np.array_equal(flip_sides(flip_sides(s.side)), s.side)


@pytest.mark.parametrize("seed", range(6))
def test_scale_crop_keep_every_map_aligned(seed: int) -> None:
    s = pattern_sample(seed)
    params = AugmentParams(
        hflip_prob=0.5,
        scale_min=0.5,
        scale_max=1.6,
        crop_height=40,
        crop_width=56,
        brightness=0,
        contrast=0,
        saturation=0,
    )
    out = augment_sample(s, params, np.random.default_rng(seed))
    assert out.label.shape == out.side.shape == (40, 56) and out.hha.shape == out.rgb.shape
    real = out.label != 255
    assert np.array_equal(out.hha[..., 0][real], out.label[real] * 50 + 1)
    coded = ((out.hha[..., 1][real] - 1) // 60).astype(np.uint8)  # the side before a flip
    assert np.array_equal(out.side[real], coded) or np.array_equal(
        out.side[real], flip_sides(coded)
    )
    # RGB (bilinear) agrees with the class 2 px away from class borders (bilinear footprint
    # and nearest-neighbour shift at scale 0.5)
    inner = cv2.erode((out.label == 1).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert np.allclose(out.rgb[inner] * 255, [200, 30, 30], atol=1.0)
    # padding: label ignored, HHA "no depth", side none
    pad = ~real
    assert not out.hha[pad].any() and not out.side[pad].any() and not out.rgb[pad].any()


def test_flip_decision_shows_in_sides() -> None:
    s = pattern_sample(1)
    params = AugmentParams(
        hflip_prob=0.5, scale_min=1, scale_max=1, brightness=0, contrast=0, saturation=0
    )
    flips = 0
    for seed in range(40):
        out = augment_sample(s, params, np.random.default_rng(seed))
        if not np.array_equal(out.label, s.label):
            flips += 1
            assert np.array_equal(out.side, flip_sides(s.side[:, ::-1]))
        else:
            assert np.array_equal(out.side, s.side)
    assert 8 <= flips <= 32  # P(outside) < 1e-4 for p = 0.5


def test_colour_jitter_changes_rgb_only() -> None:
    s = pattern_sample(2)
    base = dict(hflip_prob=0.5, scale_min=0.7, scale_max=1.3)
    plain = augment_sample(
        s, AugmentParams(**base, brightness=0, contrast=0, saturation=0), np.random.default_rng(5)
    )
    jitter = augment_sample(
        s,
        AugmentParams(**base, brightness=0.5, contrast=0.5, saturation=0.5),
        np.random.default_rng(5),
    )
    for name in ("hha", "label", "side"):
        assert np.array_equal(getattr(plain, name), getattr(jitter, name))
    assert not np.allclose(plain.rgb, jitter.rgb) and 0 <= jitter.rgb.min() <= jitter.rgb.max() <= 1


def test_dataset_augmentation_is_a_function_of_seed_epoch_and_index(simulated: Path) -> None:
    params = AugmentParams(scale_min=0.7, scale_max=1.3)
    a = SegmentationFolder(simulated, augment=params, seed=1)
    b = SegmentationFolder(simulated, augment=params, seed=1)
    a.set_epoch(0)
    b.set_epoch(0)
    x, y = a[2], b[2]
    assert all(np.array_equal(x[k], y[k]) for k in ("rgb", "hha", "label", "side"))
    assert np.array_equal(a[2]["rgb"], x["rgb"])  # a function of (seed, epoch, index)
    b.set_epoch(1)
    assert not np.array_equal(b[2]["rgb"], x["rgb"])
    # without set_epoch: torch's generator seeds each read (epochs differ, runs repeat)
    c = SegmentationFolder(simulated, augment=params, seed=1)
    torch.manual_seed(0)
    first, second = c[2]["rgb"], c[2]["rgb"]
    assert not np.array_equal(first, second)
    torch.manual_seed(0)
    assert np.array_equal(c[2]["rgb"], first)
    plain = SegmentationFolder(simulated, augment=NO_AUG)[0]
    direct = SegmentationFolder(simulated)[0]
    assert all(np.array_equal(plain[k], direct[k]) for k in ("rgb", "hha", "label", "side"))


def test_augment_params_are_checked() -> None:
    with pytest.raises(ValueError, match="hflip_prob"):
        AugmentParams(hflip_prob=1.5)
    with pytest.raises(ValueError, match="scale_max"):
        AugmentParams(scale_min=1.2, scale_max=1.0)
    with pytest.raises(ValueError, match="crop_width"):
        AugmentParams(crop_width=-1)


def test_make_segmentation_splits_script(tmp_path: Path, capsys) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "make_segmentation_splits", ROOT / "data" / "make_segmentation_splits.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    handmade(tmp_path)
    assert script.main([str(tmp_path), "--check"]) == 0
    ids = sum((read_split(tmp_path / f"{n}.txt", tmp_path) for n in ("train", "val", "test")), [])
    assert ids == ["a"] and (tmp_path / "hha" / "a.png").is_file()
    (tmp_path / "train.txt").write_text("a\n")
    assert script.main([str(tmp_path)]) == 0  # existing split files are kept
    assert (tmp_path / "train.txt").read_text() == "a\n"
    (tmp_path / "depth" / "a.png").unlink()
    assert script.main([str(tmp_path), "--check"]) == 1
    assert "depth/a.png: depth image not found" in capsys.readouterr().err
    assert script.main([str(tmp_path / "nothing")]) == 1


@pytest.mark.parametrize("key", ["brightness", "contrast", "saturation"])
def test_each_colour_jitter_acts_alone(key: str) -> None:
    s = pattern_sample(4)
    off = dict(hflip_prob=0, scale_min=1, scale_max=1, brightness=0, contrast=0, saturation=0)
    plain = augment_sample(s, AugmentParams(**off), np.random.default_rng(0))
    one = augment_sample(s, AugmentParams(**{**off, key: 0.5}), np.random.default_rng(0))
    assert np.allclose(plain.rgb * 255, s.rgb, atol=1e-3)
    assert not np.allclose(plain.rgb, one.rgb, atol=1e-3)
