"""DCT (eq. 4.2/4.3), the DCT-GCN predictor, its losses (4.5/4.6) and ONNX export/runtime."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.fft
import torch

from gaitnet.evaluation.metrics import mean_angle_error, mpjpe
from gaitnet.motion.dct import dct_matrix, dct_matrix_torch, idct_matrix, idct_matrix_torch
from gaitnet.motion.gcn import (
    DCTGCN,
    GraphConvolution,
    PredictorConfig,
    joint_positions,
    pose_features,
    split_pose_features,
)
from gaitnet.motion.losses import motion_loss
from gaitnet.motion.onnx_runtime import (
    OnnxInputError,
    OnnxParityError,
    OnnxPredictor,
    export_predictor_onnx,
)
from gaitnet.motion.skeleton import builtin_skeleton, forward_kinematics

SMALL = PredictorConfig(hidden=16, n_blocks=2)

# --------------------------------------------------------------------------- DCT


@pytest.mark.parametrize("n", [1, 2, 15, 20, 33])
def test_dct_matrix_is_orthonormal_and_idct_is_its_transpose(n: int) -> None:
    D = dct_matrix(n)
    np.testing.assert_allclose(D @ D.T, np.eye(n), atol=1e-12)
    np.testing.assert_array_equal(idct_matrix(n), D.T)
    np.testing.assert_allclose(idct_matrix(n) @ D, np.eye(n), atol=1e-12)


@pytest.mark.parametrize("n", [5, 20])
def test_dct_matches_scipy_ortho_dct2(n: int) -> None:
    x = np.random.default_rng(n).normal(size=(n, 7))
    np.testing.assert_allclose(
        dct_matrix(n) @ x, scipy.fft.dct(x, type=2, norm="ortho", axis=0), atol=1e-12
    )
    c = scipy.fft.dct(x, type=2, norm="ortho", axis=0)
    np.testing.assert_allclose(idct_matrix(n) @ c, x, atol=1e-12)


def test_dct_matches_thesis_eq_4_2_written_out() -> None:
    T = 6
    x = np.random.default_rng(3).normal(size=T)
    C = np.zeros(T)
    for l in range(1, T + 1):  # noqa: E741 (the thesis's index)
        for n in range(1, T + 1):
            C[l - 1] += (
                np.sqrt(2 / T)
                * x[n - 1]
                / np.sqrt(1 + (l == 1))
                * np.cos(np.pi / (2 * T) * (2 * n - 1) * (l - 1))
            )
    np.testing.assert_allclose(dct_matrix(T) @ x, C, atol=1e-12)


def test_dct_torch_matches_numpy() -> None:
    D = dct_matrix_torch(20, dtype=torch.float64)
    assert D.dtype == torch.float64
    np.testing.assert_array_equal(D.numpy(), dct_matrix(20))
    np.testing.assert_array_equal(idct_matrix_torch(20, dtype=torch.float64).numpy(), D.numpy().T)
    assert dct_matrix_torch(4).dtype == torch.float32
    with pytest.raises(ValueError, match="positive integer"):
        dct_matrix(0)


# --------------------------------------------------------------------------- GCN


@pytest.mark.parametrize("dct_n", [20, 15])
def test_gcn_output_shapes(dct_n: int) -> None:
    torch.manual_seed(0)
    model = DCTGCN(PredictorConfig(hidden=16, n_blocks=2, dct_n=dct_n))
    x = torch.randn(4, 10, 21)
    model.train()
    y = model(x)
    assert y.shape == (4, 20, 21)
    y.sum().backward()  # trainable end to end
    assert model.gc1.att.grad is not None and model.gc7.weight.grad is not None
    model.eval()
    assert model.predict_future(x).shape == (4, 10, 21)
    assert model.dct_m.shape == (dct_n, 20) and model.idct_m.shape == (20, dct_n)
    # Derived buffers are not part of the checkpoint.
    assert not any(k in model.state_dict() for k in ("dct_m", "idct_m", "pad_idx"))


def test_gcn_thesis_defaults_and_param_names() -> None:
    cfg = PredictorConfig()
    assert (cfg.n_past, cfg.n_future, cfg.dct_n, cfg.n_nodes) == (10, 10, 20, 21)
    assert (cfg.hidden, cfg.n_blocks, cfg.dropout) == (256, 12, 0.5)
    model = DCTGCN(cfg)
    assert len(model.gcbs) == 12
    assert model.gc1.att.shape == (21, 21) and model.gc1.weight.shape == (20, 256)
    assert model.gcbs[0].bn1.num_features == 21 * 256
    assert model.gc7.weight.shape == (256, 20)


def test_gcn_config_and_input_validation() -> None:
    with pytest.raises(ValueError, match="dct_n"):
        PredictorConfig(dct_n=21)
    with pytest.raises(ValueError, match="dropout"):
        PredictorConfig(dropout=1.0)
    model = DCTGCN(SMALL).eval()
    with pytest.raises(ValueError, match=r"\(batch, 10, 21\)"):
        model(torch.zeros(2, 9, 21))


def test_graph_convolution_is_A_H_W_plus_b() -> None:
    gc = GraphConvolution(3, 2, n_nodes=4)
    H = torch.randn(5, 4, 3)
    expected = gc.att @ H @ gc.weight + gc.bias
    torch.testing.assert_close(gc(H), expected)


def _zero_parameters(model: torch.nn.Module) -> None:
    with torch.no_grad():
        for p in model.parameters():
            p.zero_()


def test_global_residual_with_zero_weights_repeats_last_pose() -> None:
    model = DCTGCN(SMALL)
    _zero_parameters(model)
    model.eval()
    x = torch.randn(3, 10, 21)
    y = model(x)
    torch.testing.assert_close(y[:, :10], x, atol=1e-5, rtol=0)
    torch.testing.assert_close(y[:, 10:], x[:, -1:].expand(-1, 10, -1), atol=1e-5, rtol=0)


def _trained_like(cfg: PredictorConfig, seed: int = 0) -> DCTGCN:
    """A model with random weights and non-trivial batch-norm statistics, in eval mode."""
    torch.manual_seed(seed)
    model = DCTGCN(cfg)
    model.train()
    with torch.no_grad():
        for _ in range(3):
            model(0.5 * torch.randn(16, 10, 21))
    return model.eval()


def test_last_pose_residual_keeps_a_still_input_exactly_still() -> None:
    still = torch.randn(6, 1, 21).expand(-1, 10, -1).contiguous()
    ours = _trained_like(PredictorConfig(hidden=16, n_blocks=2, residual="last_pose"))
    with torch.no_grad():
        out = ours(still)
    assert torch.equal(out, still[:, :1].expand(-1, 20, -1))  # bit for bit
    # LTD's residual alone does not: the same kind of network invents motion
    ltd = _trained_like(PredictorConfig(hidden=16, n_blocks=2, residual="ltd"))
    with torch.no_grad():
        assert (ltd(still) - still[:, :1]).abs().max() > 1e-2
    # a moving input moves, and the prediction starts from the last observed pose's side
    moving = torch.cumsum(0.02 * torch.randn(6, 10, 21), dim=1)
    with torch.no_grad():
        assert (ours(moving)[:, 10:] - moving[:, -1:]).abs().max() > 1e-4


def test_velocity_padding_known_answer_and_still_input() -> None:
    """With zero weights the output is the padded input: the damped last step, eq. by hand."""
    model = DCTGCN(
        PredictorConfig(hidden=8, n_blocks=1, residual="last_pose", pad_velocity_decay=0.5)
    )
    _zero_parameters(model)
    model.eval()
    x = torch.cumsum(torch.full((1, 10, 21), 0.1), dim=1)  # each node moves 0.1 per frame
    with torch.no_grad():
        y = model(x)[0, 10:, 0]
    expected = 1.0 + 0.1 * torch.tensor([0.5, 0.75, 0.875, 0.9375, 0.96875]).double()
    torch.testing.assert_close(y[:5].double(), expected, atol=1e-6, rtol=0)
    ours = _trained_like(PredictorConfig(hidden=16, n_blocks=2, residual="last_pose",
                                         pad_velocity_decay=0.8))  # fmt: skip
    still = torch.randn(5, 1, 21).expand(-1, 10, -1).contiguous()
    with torch.no_grad():
        assert torch.equal(ours(still), still[:, :1].expand(-1, 20, -1))
    with pytest.raises(ValueError, match="pad_velocity_decay"):
        PredictorConfig(pad_velocity_decay=1.5)


def test_last_pose_residual_prediction_is_lipschitz_in_the_motion() -> None:
    """A nearly still input (sway) gives a nearly still prediction: the output moves away
    from the last pose by an amount proportional to the input's motion."""
    model = _trained_like(PredictorConfig(hidden=16, n_blocks=2, residual="last_pose"), seed=3)
    base = torch.randn(4, 1, 21).expand(-1, 10, -1)
    wiggle = torch.randn(4, 10, 21)
    with torch.no_grad():
        dev = [
            (model(base + eps * wiggle)[:, 10:] - (base + eps * wiggle)[:, -1:]).abs().max()
            for eps in (1e-3, 1e-4)
        ]
    assert 0 < dev[1] < 0.2 * dev[0]  # ten times less motion, about ten times less deviation


def test_last_pose_residual_exports_to_onnx_and_stays_still(tmp_path: Path) -> None:
    model = _trained_like(PredictorConfig(hidden=16, n_blocks=1, residual="last_pose"))
    path = tmp_path / "still.onnx"
    assert export_predictor_onnx(model, path).max_abs_diff <= 1e-4
    still = np.repeat(np.random.default_rng(0).normal(size=(3, 1, 21)), 10, axis=1)
    got = OnnxPredictor(path, threads=1)(still)
    assert np.abs(got - still[:, :1].astype(np.float32)).max() <= 1e-6


def test_truncated_dct_low_passes_the_padded_input() -> None:
    model = DCTGCN(PredictorConfig(hidden=16, n_blocks=2, dct_n=15))
    _zero_parameters(model)
    model.eval()
    x = torch.randn(2, 10, 21, dtype=torch.float64)
    model.double()
    padded = torch.cat([x, x[:, -1:].expand(-1, 10, -1)], dim=1).numpy()
    D = dct_matrix(20)
    expected = D[:15].T @ (D[:15] @ padded)
    # The DCT buffers are float32 (the exported precision), hence the tolerance.
    np.testing.assert_allclose(model(x).detach().numpy(), expected, atol=1e-6)
    assert np.abs(expected - padded).max() > 1e-3  # 15 < 20 coefficients really smooth


# --------------------------------------------------------------------------- features, losses


def test_pose_features_round_trip() -> None:
    rng = np.random.default_rng(0)
    root, joints = rng.normal(size=(5, 3)), rng.normal(size=(5, 8, 3))
    f = pose_features(root, joints)
    assert f.shape == (5, 21)
    r2, j2 = split_pose_features(f)
    np.testing.assert_array_equal(r2, root)
    np.testing.assert_array_equal(j2, joints[:, :6])
    rt, jt = split_pose_features(torch.from_numpy(f))
    assert rt.shape == (5, 3) and jt.shape == (5, 6, 3)


def test_losses_known_answers() -> None:
    skel = builtin_skeleton(1.75)
    rng = np.random.default_rng(1)
    pose = torch.from_numpy(0.3 * rng.normal(size=(2, 20, 21)))
    # Identical poses: zero loss, finite gradients.
    pred = pose.clone().requires_grad_(True)
    loss = motion_loss(pred, pose, skel, w_mpjpe=2.0, w_mae=0.5)
    assert all(float(v.detach()) == 0.0 for v in loss)
    loss.total.backward()
    assert torch.isfinite(pred.grad).all()
    # A pure translation offset d moves every joint by d: MPJPE = |d|.
    d = torch.tensor([0.03, -0.04, 0.12], dtype=torch.float64)
    p = joint_positions(pose, skel)
    p_off = joint_positions(pose, skel, trans=d.expand(2, 20, 3))
    assert p.shape == (2, 20, 7, 3)
    torch.testing.assert_close(mpjpe(p_off, p), torch.linalg.norm(d))
    # Eq. (4.6): a constant offset (0.1, -0.2, 0.3) on every joint gives 0.6.
    off = torch.tensor([0.1, -0.2, 0.3], dtype=torch.float64).repeat(7)
    torch.testing.assert_close(mean_angle_error(pose + off, pose), torch.tensor(0.6).double())
    terms = motion_loss(pose + off, pose, skel, w_mpjpe=2.0, w_mae=0.5)
    torch.testing.assert_close(terms.total, 2.0 * terms.mpjpe + 0.5 * terms.mae)
    assert float(terms.mpjpe) > 0


def test_joint_positions_match_numpy_forward_kinematics() -> None:
    skel = builtin_skeleton(1.6)
    f = np.random.default_rng(2).normal(scale=0.4, size=(3, 21))
    root, body = split_pose_features(f)
    aa = np.concatenate([body, np.zeros((3, 2, 3))], axis=1)
    expected = forward_kinematics(skel, root, np.zeros((3, 3)), aa)[:, :7]
    got = joint_positions(torch.from_numpy(f), skel).numpy()
    np.testing.assert_allclose(got, expected, atol=1e-12)
    np.testing.assert_allclose(joint_positions(f, skel), expected, atol=1e-12)  # numpy path


def test_per_window_skeletons_in_the_loss_equal_one_skeleton_per_window() -> None:
    rng = np.random.default_rng(4)
    skels = [builtin_skeleton(h) for h in (1.5, 1.7, 1.95)]
    pred = torch.from_numpy(rng.normal(scale=0.4, size=(3, 20, 21)))
    target = torch.from_numpy(rng.normal(scale=0.4, size=(3, 20, 21)))
    batch = torch.from_numpy(np.stack([s.rest_joints for s in skels]))
    got = motion_loss(pred, target, batch, w_mpjpe=1.0, w_mae=0.0).mpjpe
    each = [motion_loss(pred[i : i + 1], target[i : i + 1], s).mpjpe for i, s in enumerate(skels)]
    torch.testing.assert_close(got, torch.stack(each).mean(), rtol=1e-12, atol=0)
    # taller skeletons weigh the same angle errors as larger position errors
    assert each[0] < each[2]
    with pytest.raises(ValueError, match="skeletons for a batch"):
        motion_loss(pred, target, batch[:2])


# --------------------------------------------------------------------------- ONNX


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[DCTGCN, Path, float]:
    torch.manual_seed(0)
    model = DCTGCN(SMALL)
    # Non-trivial batch-norm statistics so eval-mode export is really exercised.
    model.train()
    with torch.no_grad():
        for _ in range(3):
            model(torch.randn(8, 10, 21))
    model.eval()
    path = tmp_path_factory.mktemp("onnx") / "predictor.onnx"
    report = export_predictor_onnx(model, path, opset=18)
    return model, path, report.max_abs_diff


def test_onnx_export_parity_and_dynamic_batch(exported: tuple[DCTGCN, Path, float]) -> None:
    model, path, diff = exported
    assert path.is_file() and diff <= 1e-4
    assert not list(path.parent.glob("*.data"))  # one self-contained file
    predictor = OnnxPredictor(path, threads=1)
    assert predictor.n_past == 10 and predictor.input_shape[0] not in (1, 2)
    x = np.random.default_rng(5).normal(size=(7, 10, 21))  # float64, batch 7: both converted
    with torch.no_grad():
        expected = model(torch.from_numpy(x).float()).numpy()
    got = predictor(x)
    assert got.dtype == np.float32 and got.shape == (7, 20, 21)
    assert np.abs(got - expected).max() <= 1e-4
    np.testing.assert_array_equal(predictor.predict_future(x), got[:, 10:])


def test_onnx_predictor_rejects_wrong_input(exported: tuple[DCTGCN, Path, float]) -> None:
    _, path, _ = exported
    predictor = OnnxPredictor(path)
    with pytest.raises(OnnxInputError) as err:
        predictor(np.zeros((2, 9, 21), dtype=np.float32))
    message = str(err.value)
    assert str(path) in message and "(2, 9, 21)" in message and "('batch', 10, 21)" in message
    with pytest.raises(OnnxInputError, match="shape"):
        predictor(np.zeros((10, 21), dtype=np.float32))
    with pytest.raises(OnnxInputError, match="dtype"):
        predictor(np.zeros((1, 10, 21), dtype=np.complex64))
    with pytest.raises(OnnxInputError, match="does not exist"):
        OnnxPredictor(path.parent / "missing.onnx")
    with pytest.raises(OnnxInputError, match=r"NaN/inf.*index \(1, 3, 4\)"):
        x = np.zeros((2, 10, 21))
        x[1, 3, 4] = np.nan
        predictor(x)
    with pytest.raises(OnnxInputError, match="beyond float32"):
        predictor(np.full((1, 10, 21), 1e300))  # finite in float64, inf in float32
    with pytest.raises(OnnxInputError, match="empty batch"):
        predictor(np.zeros((0, 10, 21), dtype=np.float32))


def test_export_refuses_when_parity_fails(tmp_path: Path) -> None:
    model = DCTGCN(PredictorConfig(hidden=8, n_blocks=1)).eval()
    path = tmp_path / "bad.onnx"
    with pytest.raises(OnnxParityError, match="exceeds"):
        export_predictor_onnx(model, path, atol=-1.0)  # no graph can meet a negative tolerance
    assert list(tmp_path.iterdir()) == []  # nothing written, temporary file removed
