"""Rest joints from body-model files agree with smplx; file layouts and clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from amassfactory import (
    SMPLH_PARENTS,
    make_body_model,
    write_chumpy_pickle,
    write_model_npz,
    write_model_pkl,
)

from gaitnet.motion.body_model import (
    BodyModelError,
    find_model_file,
    load_shape_model,
    lower_body_skeleton,
)
from gaitnet.motion.skeleton import ROTATED_SMPL_INDICES, SMPL_JOINT_INDICES, forward_kinematics


@pytest.fixture(scope="module")
def model_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path, Path]:
    folder = tmp_path_factory.mktemp("models")
    model = make_body_model(np.random.default_rng(0))
    npz = write_model_npz(folder / "smpl" / "SMPL_NEUTRAL.npz", model)
    pkl = write_model_pkl(folder / "SMPL_NEUTRAL.pkl", model, sparse_regressor=True)
    return model, npz, pkl


def test_forward_kinematics_matches_smplx_joints(model_files: tuple[dict, Path, Path]) -> None:
    model, npz, pkl = model_files
    # smplx is an optional test dependency: only this comparison needs it.
    smplx = pytest.importorskip("smplx")
    smplx_vertex_ids = pytest.importorskip("smplx.vertex_ids").vertex_ids
    # Small vertex ids: the test mesh has 300 vertices, smplx's defaults index up to 6889.
    small_ids = {k: i for i, k in enumerate(smplx_vertex_ids["smplh"])}
    body = smplx.SMPL(model_path=str(pkl), vertex_ids=small_ids, dtype=torch.float64)
    rng = np.random.default_rng(1)
    shape_model = load_shape_model(npz)
    for _ in range(4):
        betas = rng.normal(size=10)
        B = 3
        global_orient = rng.normal(scale=0.8, size=(B, 3))
        body_pose = rng.normal(scale=0.5, size=(B, 69))
        transl = rng.normal(size=(B, 3))
        out = body(
            betas=torch.from_numpy(np.tile(betas, (B, 1))),
            global_orient=torch.from_numpy(global_orient),
            body_pose=torch.from_numpy(body_pose),
            transl=torch.from_numpy(transl),
        )
        expected = out.joints.detach().numpy()[:, list(SMPL_JOINT_INDICES)]
        skel = shape_model.skeleton(betas)
        full = np.concatenate([global_orient, body_pose], axis=1).reshape(B, 24, 3)
        got = forward_kinematics(skel, global_orient, transl, full[:, list(ROTATED_SMPL_INDICES)])
        assert got.shape == (B, 9, 3)
        np.testing.assert_allclose(got, expected, atol=1e-5, rtol=0)


def test_npz_and_sparse_pickle_give_the_same_joints(model_files: tuple[dict, Path, Path]) -> None:
    model, npz, pkl = model_files
    betas = np.random.default_rng(2).normal(size=10)
    a = load_shape_model(npz).rest_joints(betas)
    b = load_shape_model(pkl).rest_joints(betas)
    expected = model["J_regressor"] @ (model["v_template"] + model["shapedirs"] @ betas)
    np.testing.assert_allclose(a, expected, atol=1e-12)
    np.testing.assert_allclose(b, expected, atol=1e-12)
    skel = lower_body_skeleton(npz.parent.parent, "neutral", betas, model_type="smpl")
    np.testing.assert_allclose(skel.rest_joints, expected[list(SMPL_JOINT_INDICES)], atol=1e-12)


def test_amass_extended_smplh_model_without_hand_pca(tmp_path: Path) -> None:
    # AMASS's SMPL+H model.npz: 52 joints, 16 betas, no hands_components*/hands_mean*.
    model = make_body_model(np.random.default_rng(3), parents=SMPLH_PARENTS, n_betas=16)
    write_model_npz(tmp_path / "smplh" / "female" / "model.npz", model)
    betas = np.random.default_rng(4).normal(size=16)
    path = find_model_file(tmp_path, "female", "smplh")
    assert path == tmp_path / "smplh" / "female" / "model.npz"
    skel = lower_body_skeleton(tmp_path, "female", betas, model_type="smplh")
    expected = model["J_regressor"] @ (model["v_template"] + model["shapedirs"] @ betas)
    np.testing.assert_allclose(skel.rest_joints, expected[list(SMPL_JOINT_INDICES)], atol=1e-12)
    # All 16 betas are used: the 16th changes the joints.
    b15 = betas.copy()
    b15[15] = 0.0
    assert not np.allclose(lower_body_skeleton(path, betas=b15).rest_joints, skel.rest_joints)


def test_chumpy_pickle_is_refused_with_the_fix(tmp_path: Path) -> None:
    path = write_chumpy_pickle(tmp_path / "SMPL_MALE.pkl")
    with pytest.raises(BodyModelError, match=r"SMPL_MALE\.pkl.*chumpy.*clean_ch\.py"):
        load_shape_model(path)


def test_clear_errors(tmp_path: Path, model_files: tuple[dict, Path, Path]) -> None:
    model, npz, _ = model_files
    partial = {k: v for k, v in model.items() if k != "J_regressor"}
    path = write_model_npz(tmp_path / "partial.npz", partial)
    with pytest.raises(BodyModelError, match=r"partial\.npz.*'J_regressor'"):
        load_shape_model(path)
    with pytest.raises(BodyModelError, match="non-zero entries beyond 10"):
        load_shape_model(npz).rest_joints(np.arange(1, 17, dtype=float))
    np.testing.assert_allclose(  # trailing zeros are fine (AMASS pads betas to 16)
        load_shape_model(npz).rest_joints(np.r_[np.ones(10), np.zeros(6)]),
        load_shape_model(npz).rest_joints(np.ones(10)),
    )
    bad_tree = dict(model)
    kt = model["kintree_table"].copy()
    kt[0, 4] = 2  # L_knee hung from R_hip
    bad_tree["kintree_table"] = kt
    with pytest.raises(BodyModelError, match="kintree_table"):
        load_shape_model(write_model_npz(tmp_path / "tree.npz", bad_tree))
    with pytest.raises(BodyModelError, match="no male body model found"):
        find_model_file(tmp_path, "male")
    with pytest.raises(BodyModelError, match="does not exist"):
        find_model_file(tmp_path / "nowhere")
