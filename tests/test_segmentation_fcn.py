"""FCN-8s on torchvision's VGG16 and the RGB / HHA / late-fusion segmenter
(gaitnet.segmentation.fcn): the published architecture (layer shapes, parameter count), exact
output sizes, aligned score maps for both paddings, bilinear upsampling, late fusion as a sum,
width scaling, input scaling, local VGG16 weights and checkpoints."""

from __future__ import annotations

import math
import pickle

import pytest
import torch
import torchvision
from torch import nn
from torch.nn import functional as nnf

from gaitnet.errors import ConfigError, InputError
from gaitnet.segmentation.channels import ARCHS, input_channels
from gaitnet.segmentation.fcn import (
    OUTPUT_STRIDES,
    PADDINGS,
    FCN8s,
    bilinear_kernel,
    fcn8s_parameter_count,
)
from gaitnet.segmentation.segmenter_net import (
    SegmenterNet,
    build_segmenter,
    model_input,
    segmenter_from_checkpoint,
)

SMALL = 1 / 16

# The published FCN-8s (VGG16 conv layers, fc6 7x7, fc7 1x1, three score layers, three
# transposed convolutions without bias), written out layer by layer.
VGG16_CONVS = [(3, 64), (64, 64), (64, 128), (128, 128), (128, 256), (256, 256), (256, 256),
               (256, 512), (512, 512), (512, 512), (512, 512), (512, 512), (512, 512)]  # fmt: skip


def published_count(n: int) -> int:
    convs = sum(cin * cout * 3 * 3 + cout for cin, cout in VGG16_CONVS)
    fc6 = 512 * 7 * 7 * 4096 + 4096
    fc7 = 4096 * 4096 + 4096
    scores = (4096 * n + n) + (512 * n + n) + (256 * n + n)
    upscores = n * n * 4 * 4 + n * n * 4 * 4 + n * n * 16 * 16
    return convs + fc6 + fc7 + scores + upscores


def n_params(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


def randomise(net: nn.Module, seed: int = 0) -> nn.Module:
    """Small random weights everywhere (score layers start at zero, which hides everything)."""
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(0.1 * torch.randn(p.shape, generator=gen))
    return net.eval()


def test_published_parameter_count() -> None:
    # The FCN paper lists 134M parameters for FCN-VGG16 (21 PASCAL classes).
    assert 134.0e6 < published_count(21) < 135.0e6
    with torch.device("meta"):
        assert n_params(FCN8s(21)) == published_count(21)
        assert n_params(FCN8s(3)) == published_count(3)
        assert n_params(SegmenterNet("rgb")) == published_count(3)
        assert n_params(SegmenterNet("hha")) == published_count(3)
        assert n_params(SegmenterNet("fusion")) == 2 * published_count(3)
    assert fcn8s_parameter_count(3) == published_count(3)


def test_published_layer_shapes() -> None:
    with torch.device("meta"):
        net = SegmenterNet("fusion")
        reference = torchvision.models.vgg16(weights=None)
    for stream in (net.rgb, net.hha):
        assert stream is not None
        ours = {k: v.shape for k, v in stream.features.state_dict().items()}
        theirs = {k: v.shape for k, v in reference.features.state_dict().items()}
        assert ours == theirs  # torchvision's VGG16 feature layers
        conv1_1 = stream.features[0]
        assert conv1_1.padding == (100, 100)
        pools = [m for m in stream.features if isinstance(m, nn.MaxPool2d)]
        assert len(pools) == 5 and all(p.ceil_mode for p in pools)
        assert stream.fc6.weight.shape == (4096, 512, 7, 7)
        assert stream.fc7.weight.shape == (4096, 4096, 1, 1)
        assert stream.score_fr.weight.shape == (3, 4096, 1, 1)
        assert stream.score_pool4.weight.shape == (3, 512, 1, 1)
        assert stream.score_pool3.weight.shape == (3, 256, 1, 1)
        for name, k, s in (("upscore2", 4, 2), ("upscore_pool4", 4, 2), ("upscore8", 16, 8)):
            layer = getattr(stream, name)
            assert layer.weight.shape == (3, 3, k, k) and layer.stride == (s, s)
            assert layer.bias is None


def pool_sizes_at_640x480(stream: FCN8s) -> list[tuple[int, ...]]:
    """The (H, W) after each pooling layer for a 640×480 input (on the meta device); checks
    the stream's output is the input's size."""
    h = torch.empty(1, 3, 480, 640)
    sizes = []
    for layer in stream.features:
        h = layer(h)
        if isinstance(layer, nn.MaxPool2d):
            sizes.append(tuple(h.shape[2:]))
    assert stream(torch.empty(1, 3, 480, 640)).shape == (1, 3, 480, 640)
    return sizes


def test_feature_map_sizes_at_640x480() -> None:
    """Pool sizes by hand: conv1_1 pad 100 → 678 × 838, then ceil(x / 2) five times."""
    with torch.device("meta"):
        sizes = pool_sizes_at_640x480(FCN8s(3))
    expected, hw = [], (480 + 198, 640 + 198)
    for _ in range(5):
        hw = (math.ceil(hw[0] / 2), math.ceil(hw[1] / 2))
        expected.append(hw)
    assert sizes == expected == [(339, 419), (170, 210), (85, 105), (43, 53), (22, 27)]


def test_same_padding_feature_map_sizes_at_640x480() -> None:
    """conv1_1 padded by 1 keeps 480 × 640; then ceil(x / 2) five times."""
    with torch.device("meta"):
        stream = FCN8s(3, padding="same")
        sizes = pool_sizes_at_640x480(stream)
        assert stream.fc6(torch.empty(1, 512, 15, 20)).shape == (1, 4096, 15, 20)
    assert sizes == [(240, 320), (120, 160), (60, 80), (30, 40), (15, 20)]
    assert n_params(FCN8s(3, padding="same")) == published_count(3)


def _linear_stream(padding: str, path: str, output_stride: int = 8) -> FCN8s:
    """A stream made linear (average instead of max pooling, positive constant weights, zero
    biases: the ReLUs pass everything) whose output is one score path alone."""
    stream = FCN8s(1, width=SMALL, padding=padding, output_stride=output_stride).eval()
    for i, layer in enumerate(stream.features):
        if isinstance(layer, nn.MaxPool2d):
            stream.features[i] = nn.AvgPool2d(2, 2, ceil_mode=True)
    with torch.no_grad():
        for m in [*stream.features, stream.fc6, stream.fc7]:
            if isinstance(m, nn.Conv2d):
                m.weight.fill_(1.0 / m.weight[0].numel())
                m.bias.zero_()
        for name, layer in stream.named_children():
            if name.startswith("score_"):
                layer.weight.fill_(1.0 if name == path else 0.0)
                layer.bias.zero_()
    return stream


#: The score paths of each output stride.
SCORE_PATHS = {
    8: ["score_fr", "score_pool4", "score_pool3"],
    4: ["score_fr", "score_pool4", "score_pool3", "score_pool2"],
    2: ["score_fr", "score_pool4", "score_pool3", "score_pool2", "score_pool1"],
}


@pytest.mark.parametrize("padding", PADDINGS)
@pytest.mark.parametrize(
    ("output_stride", "path"), [(s, p) for s in OUTPUT_STRIDES for p in SCORE_PATHS[s]]
)
def test_score_paths_are_aligned_with_the_input(padding: str, output_stride: int, path: str):
    """Each score path of a linearised stream answers a 2 × 2 impulse at the centre of a
    256 × 256 input with a response centred on it: an offset one cell off moves it by 0.8–10
    pixels (checked by hand), the sampling grid's phase by < 0.25."""
    x = torch.zeros(1, 3, 256, 256)
    x[..., 127:129, 127:129] = 1.0
    with torch.no_grad():
        y = _linear_stream(padding, path, output_stride)(x)[0, 0].double()
    assert y.shape == (256, 256) and float(y.min()) >= 0.0 and float(y.max()) > 0.0
    idx = torch.arange(256, dtype=torch.float64)
    centre = (float((y.sum(1) * idx).sum() / y.sum()), float((y.sum(0) * idx).sum() / y.sum()))
    assert centre == pytest.approx((127.5, 127.5), abs=0.25)


def test_finer_output_strides_add_skips_from_pool2_and_pool1() -> None:
    """Stride 4 adds score_pool2 and a learned ×2 (upscore_pool3) and ends with a fixed
    bilinear ×4; stride 2 adds pool1 too and ends with ×2; the count formula matches."""
    for stride, final, kernel in ((8, "upscore8", 16), (4, "upscore4", 8), (2, "upscore_out", 4)):
        stream = FCN8s(3, width=SMALL, output_stride=stride)
        scores = {n for n, _ in stream.named_children() if n.startswith("score_")}
        assert scores == set(SCORE_PATHS[stride])
        out = getattr(stream, final)
        assert out.stride == (stride, stride) and not out.weight.requires_grad
        assert torch.equal(out.weight[1, 1], bilinear_kernel(kernel))
        learned = [n for n, m in stream.named_children()
                   if isinstance(m, nn.ConvTranspose2d) and m.weight.requires_grad]  # fmt: skip
        assert len(learned) == len(SCORE_PATHS[stride]) - 1  # one ×2 per fused skip
        for name in learned:
            assert torch.equal(getattr(stream, name).weight[2, 2], bilinear_kernel(4)), name
        n = sum(p.numel() for p in stream.parameters())
        assert n == fcn8s_parameter_count(3, SMALL, output_stride=stride)
    c1, c2 = round(64 * SMALL), round(128 * SMALL)
    by_hand = (c2 + 1) * 3 + 3 * 3 * 4 * 4 + 3 * 3 * (8 * 8 - 16 * 16)  # score_pool2 etc.
    assert (
        fcn8s_parameter_count(3, SMALL, output_stride=4) - fcn8s_parameter_count(3, SMALL)
        == by_hand
    )
    assert fcn8s_parameter_count(3, SMALL, output_stride=2) - fcn8s_parameter_count(
        3, SMALL, output_stride=4
    ) == (c1 + 1) * 3 + 3 * 3 * 4 * 4 + 3 * 3 * (4 * 4 - 8 * 8)
    with pytest.raises(ConfigError, match="output_stride"):
        FCN8s(3, width=SMALL, output_stride=16)
    with pytest.raises(ConfigError, match="output_stride"):
        SegmenterNet("rgb", width=SMALL, output_stride=True)


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize("scale", [1.0, 0.5])
@pytest.mark.parametrize("padding", PADDINGS)
@pytest.mark.parametrize("stride", OUTPUT_STRIDES)
def test_output_is_exactly_the_input_size(arch: str, scale: float, padding: str, stride: int):
    net = SegmenterNet(arch, width=SMALL, input_scale=scale, padding=padding, output_stride=stride)
    net = randomise(net)
    for h, w in [(1, 1), (37, 53), (31, 66), (97, 130)]:
        x = torch.rand(2, input_channels(arch), h, w)
        with torch.no_grad():
            y = net(x)
        assert y.shape == (2, 3, h, w)
        assert torch.isfinite(y).all()


def test_bilinear_kernel_by_hand() -> None:
    f4 = torch.tensor([0.25, 0.75, 0.75, 0.25])
    assert torch.allclose(bilinear_kernel(4), torch.outer(f4, f4))
    f16 = torch.tensor([1, 3, 5, 7, 9, 11, 13, 15, 15, 13, 11, 9, 7, 5, 3, 1]) / 16
    assert torch.allclose(bilinear_kernel(16), torch.outer(f16, f16))


def test_transposed_convs_start_bilinear() -> None:
    stream = FCN8s(3, width=SMALL)
    for name, k in (("upscore2", 4), ("upscore_pool4", 4), ("upscore8", 16)):
        w = getattr(stream, name).weight.detach()
        for i in range(3):
            for j in range(3):
                expected = bilinear_kernel(k) if i == j else torch.zeros(k, k)
                assert torch.equal(w[i, j], expected), (name, i, j)
    # The final ×8 upsampling stays bilinear, the two ×2 learn (the reference nets).
    assert not stream.upscore8.weight.requires_grad
    assert stream.upscore2.weight.requires_grad and stream.upscore_pool4.weight.requires_grad
    # Bilinear interpolation reproduces a linear ramp away from the borders, per class.
    ramp = torch.arange(10.0).view(1, 1, 1, 10).expand(1, 3, 10, 10).clone()
    ramp[:, 1] *= -2.0
    with torch.no_grad():
        up = stream.upscore8(ramp)
    # input pixel i lands at output 8 i + 7.5 (kernel 16, stride 8): output o between two
    # input pixels (8 ≤ o ≤ 79 for 10 inputs) is at input coordinate (o - 7.5) / 8
    o = torch.arange(up.shape[3], dtype=torch.float32)
    inside = (o >= 8) & (o <= 79)
    assert torch.allclose(up[0, 0, 40][inside], ((o - 7.5) / 8)[inside], atol=1e-5)
    assert torch.allclose(up[0, 1, 40][inside], -2 * ((o - 7.5) / 8)[inside], atol=1e-5)
    assert not torch.allclose(up[0, 0, 40][~inside], ((o - 7.5) / 8)[~inside], atol=1e-5)


def test_score_layers_start_at_zero() -> None:
    net = SegmenterNet("fusion", width=SMALL)
    with torch.no_grad():
        assert torch.equal(net(torch.rand(1, 6, 20, 30)), torch.zeros(1, 3, 20, 30))


def test_normalisation_inside_the_net() -> None:
    rgb = randomise(SegmenterNet("rgb", width=SMALL))
    hha = randomise(SegmenterNet("hha", width=SMALL))
    x = torch.rand(1, 3, 24, 40)
    mean = torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1)
    std = torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1)
    with torch.no_grad():
        assert torch.allclose(rgb(x), rgb.rgb((x - mean) / std), atol=1e-6)
        assert torch.allclose(hha(x), hha.hha((x - 0.5) / 0.25), atol=1e-6)
    assert "mean" not in rgb.state_dict() and "std" not in rgb.state_dict()


def test_input_scale_resizes_around_the_streams() -> None:
    net = randomise(SegmenterNet("rgb", width=SMALL, input_scale=0.5))
    x = torch.rand(2, 3, 41, 61)
    mean = torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1)
    std = torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1)
    with torch.no_grad():
        small = nnf.interpolate((x - mean) / std, size=(20, 30), mode="bilinear")  # round(20.5)=20
        expected = nnf.interpolate(net.rgb(small), size=(41, 61), mode="bilinear")
        assert torch.allclose(net(x), expected, atol=1e-6)


def test_late_fusion_is_the_sum_of_the_streams() -> None:
    fusion = randomise(SegmenterNet("fusion", width=SMALL), seed=1)
    rgb = SegmenterNet("rgb", width=SMALL).eval()
    hha = SegmenterNet("hha", width=SMALL).eval()
    rgb.rgb.load_state_dict(fusion.rgb.state_dict())
    hha.hha.load_state_dict(fusion.hha.state_dict())
    x = torch.rand(2, 6, 33, 47)
    with torch.no_grad():
        both = fusion(x)
        assert torch.allclose(both, rgb(x[:, :3]) + hha(x[:, 3:]), atol=1e-5)
        assert both.abs().mean() > 1e-3  # not a trivially zero net
        # Zero the HHA stream's score layers: fusion is the RGB net alone.
        for layer in (fusion.hha.score_fr, fusion.hha.score_pool4, fusion.hha.score_pool3):
            layer.weight.zero_()
            layer.bias.zero_()
        assert torch.allclose(fusion(x), rgb(x[:, :3]), atol=1e-6)


def test_width_scales_every_layer() -> None:
    stream = FCN8s(3, width=1 / 8)
    convs = [m for m in stream.features if isinstance(m, nn.Conv2d)]
    assert [c.out_channels for c in convs] == [8, 8, 16, 16, 32, 32, 32, 64, 64, 64, 64, 64, 64]
    assert stream.fc6.weight.shape == (512, 64, 7, 7)
    assert stream.fc7.weight.shape == (512, 512, 1, 1)
    assert stream.score_pool3.weight.shape == (3, 32, 1, 1)
    channels = [3, 8, 8, 16, 16, 32, 32, 32, 64, 64, 64, 64, 64, 64]
    by_hand = sum(a * b * 9 + b for a, b in zip(channels[:-1], channels[1:], strict=True))
    by_hand += 64 * 512 * 49 + 512 + 512 * 512 + 512
    by_hand += (512 + 1) * 3 + (64 + 1) * 3 + (32 + 1) * 3 + 9 * (16 + 16 + 256)
    assert n_params(stream) == by_hand
    tiny = FCN8s(3, width=1e-3)  # every layer keeps at least one channel
    assert all(c.out_channels == 1 for c in tiny.features if isinstance(c, nn.Conv2d))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"arch": "depth"},
        {"arch": "rgb", "width": 0.0},
        {"arch": "rgb", "width": 1.5},
        {"arch": "rgb", "width": float("nan")},
        {"arch": "rgb", "input_scale": 0.0},
        {"arch": "rgb", "input_scale": 2.0},
        {"arch": "rgb", "num_classes": 1},
        {"arch": "rgb", "num_classes": 2.5},
        {"arch": "rgb", "padding": "valid"},
    ],
)
def test_bad_config_is_a_config_error(kwargs: dict) -> None:
    with pytest.raises(ConfigError, match="segmenter"):
        SegmenterNet(**kwargs)


def test_model_input_picks_channels() -> None:
    rgb, hha = torch.rand(1, 3, 4, 5), torch.rand(1, 3, 4, 5)
    assert model_input("rgb", rgb, hha) is rgb
    assert model_input("hha", rgb, hha) is hha
    assert torch.equal(model_input("fusion", rgb, hha), torch.cat([rgb, hha], 1))
    assert [input_channels(a) for a in ARCHS] == [3, 3, 6]
    with pytest.raises(InputError, match="HHA"):
        model_input("fusion", rgb, None)


def test_checkpoint_round_trip() -> None:
    net = randomise(SegmenterNet("fusion", width=SMALL, input_scale=0.5), seed=3)
    ckpt = {"model": net.state_dict(), "config": {"model": net.config(), "other": 1}}
    back = segmenter_from_checkpoint(ckpt, "run/best.pt")
    x = torch.rand(1, 6, 30, 40)
    with torch.no_grad():
        assert torch.equal(back(x), net(x))
    assert not back.training
    wrong = {"model": net.state_dict(), "config": {"model": {**net.config(), "width": 1 / 8}}}
    with pytest.raises(InputError, match=r"run/best.pt: its model state does not fit"):
        segmenter_from_checkpoint(wrong, "run/best.pt")
    with pytest.raises(InputError, match=r"run/best.pt: config.model lacks key\(s\) \['arch'\]"):
        cfg = {k: v for k, v in net.config().items() if k != "arch"}
        segmenter_from_checkpoint({"model": {}, "config": {"model": cfg}}, "run/best.pt")
    with pytest.raises(InputError, match=r"run/best.pt: config.model: .*width"):
        cfg = {**net.config(), "width": -1}
        segmenter_from_checkpoint({"model": {}, "config": {"model": cfg}}, "run/best.pt")
    with pytest.raises(InputError, match="config.model"):
        segmenter_from_checkpoint({"model": {}, "config": {}}, "run/best.pt")


def test_checkpoint_keeps_the_padding() -> None:
    """A checkpoint's padding is rebuilt; one written before the option is the published net."""
    net = randomise(SegmenterNet("hha", width=SMALL, padding="same"), seed=4)
    ckpt = {"model": net.state_dict(), "config": {"model": net.config()}}
    back = segmenter_from_checkpoint(ckpt)
    assert back.padding == "same" and back.hha is not None
    assert back.hha.features[0].padding == (1, 1) and back.hha.fc6.padding == (3, 3)
    x = torch.rand(1, 3, 40, 56)
    with torch.no_grad():
        assert torch.equal(back(x), net(x))
    old = {k: v for k, v in net.config().items() if k not in ("padding", "output_stride")}
    legacy = segmenter_from_checkpoint({"model": ckpt["model"], "config": {"model": old}})
    assert legacy.padding == "published" and legacy.hha.features[0].padding == (100, 100)
    assert legacy.output_stride == 8


def test_checkpoint_keeps_the_output_stride() -> None:
    net = randomise(SegmenterNet("fusion", width=SMALL, padding="same", output_stride=2), 5)
    back = segmenter_from_checkpoint({"model": net.state_dict(), "config": {"model": net.config()}})
    assert back.output_stride == 2 and back.rgb.score_pool1 is not None
    x = torch.rand(1, 6, 40, 56)
    with torch.no_grad():
        assert torch.equal(back(x), net(x))


def test_logit_bias_is_added_last_and_kept_by_checkpoints() -> None:
    net = randomise(SegmenterNet("fusion", width=SMALL, input_scale=0.5), 6).eval()
    biased = SegmenterNet("fusion", width=SMALL, input_scale=0.5, logit_bias=[0.0, -1.5, 0.5])
    biased.load_state_dict(net.state_dict())  # the bias is configuration, not state
    x = torch.rand(2, 6, 40, 56)
    with torch.no_grad():
        shift = biased.eval()(x) - net(x)
    torch.testing.assert_close(
        shift, torch.tensor([0.0, -1.5, 0.5]).view(1, 3, 1, 1).expand_as(shift)
    )
    assert net.config()["logit_bias"] == [0.0, 0.0, 0.0]
    back = segmenter_from_checkpoint(
        {"model": biased.state_dict(), "config": {"model": biased.config()}}
    )
    assert back.logit_bias == (0.0, -1.5, 0.5)
    old = {k: v for k, v in net.config().items() if k != "logit_bias"}  # before the option
    assert segmenter_from_checkpoint(
        {"model": net.state_dict(), "config": {"model": old}}
    ).logit_bias == (0.0, 0.0, 0.0)
    for bad in ([0.0, 1.0], [0.0, float("nan"), 0.0], "0 0 0", [0, True, 0]):
        with pytest.raises(ConfigError, match="logit_bias must be null or a list of 3"):
            SegmenterNet("rgb", width=SMALL, logit_bias=bad)


class _NotWeights:
    pass


def test_vgg16_weights_errors(tmp_path) -> None:
    with pytest.raises(ConfigError, match="width 1.0"):
        build_segmenter("rgb", width=0.5, vgg16_weights=tmp_path / "vgg16.pth")
    with pytest.raises(InputError, match="does not exist"):
        build_segmenter("rgb", width=1.0, vgg16_weights=tmp_path / "vgg16.pth")
    with pytest.raises(InputError, match="folder"):
        build_segmenter("rgb", width=1.0, vgg16_weights=tmp_path)
    foreign = tmp_path / "foreign.pth"
    torch.save({"features.0.weight": torch.zeros(2, 2)}, foreign)
    with pytest.raises(InputError, match=r"foreign.pth: not a torchvision vgg16 state dict"):
        build_segmenter("rgb", vgg16_weights=foreign)
    garbage = tmp_path / "garbage.pth"
    garbage.write_bytes(b"not a torch file")
    with pytest.raises(InputError, match="garbage.pth cannot be read"):
        build_segmenter("rgb", vgg16_weights=garbage)
    pickled = tmp_path / "pickled.pth"
    with open(pickled, "wb") as f:
        pickle.dump({"x": _NotWeights()}, f)
    with pytest.raises(InputError, match="pickled.pth"):
        build_segmenter("rgb", vgg16_weights=pickled)


def test_vgg16_weights_initialise_the_hha_stream(tmp_path) -> None:
    """A file with torchvision vgg16's keys and shapes (values made up): convs are copied,
    fc6[o, c, y, x] = classifier.0.weight[o, c*49 + y*7 + x] (torchvision flattens the 512×7×7
    pool5 map channel-first), fc7 = classifier.3; score and upsampling layers untouched."""
    with torch.device("meta"):
        shapes = {
            k: v.shape for k, v in torchvision.models.vgg16(weights=None).state_dict().items()
        }
    state = {}
    for i, (key, shape) in enumerate(shapes.items()):
        n = math.prod(shape)
        state[key] = torch.linspace(-1.0, 1.0, n).view(shape) + i
    path = tmp_path / "vgg16.pth"
    torch.save(state, path)
    net = build_segmenter("hha", vgg16_weights=path)  # HHA too, as the FCN authors did
    del state
    loaded = torch.load(path, weights_only=True)
    for stream in (net.hha,):  # the RGB stream goes through the same loop
        assert torch.equal(stream.features[0].weight, loaded["features.0.weight"])
        assert torch.equal(stream.features[28].bias, loaded["features.28.bias"])
        w6, c0 = stream.fc6.weight, loaded["classifier.0.weight"]
        for o, c, y, x in [(0, 0, 0, 0), (17, 300, 3, 5), (4095, 511, 6, 6)]:
            assert w6[o, c, y, x] == c0[o, c * 49 + y * 7 + x]
        assert torch.equal(stream.fc6.bias, loaded["classifier.0.bias"])
        assert torch.equal(stream.fc7.weight[:, :, 0, 0], loaded["classifier.3.weight"])
        assert torch.equal(stream.fc7.bias, loaded["classifier.3.bias"])
        assert torch.count_nonzero(stream.score_fr.weight) == 0
        assert torch.equal(stream.upscore8.weight[1, 1], bilinear_kernel(16))
