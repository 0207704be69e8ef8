"""Pose correction (eq. 4.7, 4.8): speed and accuracy, naive L-BFGS versus Levenberg-Marquardt.

On a simulated session's ground truth (``groundtruth/joints.npz``, ``feet.csv``,
``camera_frames.tum``, ``marker_pixels.csv``, ``events.csv``; docs/groundtruth.md) it

1. estimates the camera-to-pelvis extrinsic from the standing frames before the first toe off
   (noisy camera poses and foot points, the rest pose as the standing pose) and compares it
   with the simulator's true mount at the first frame;
2. builds per-frame priors (the true pose with the errors a predictor makes, drawn: Gaussian
   axis-angle errors per joint, a root orientation and a root position error) and measurements
   (the pelvis through the estimated extrinsic from noisy camera poses; the shoe-top marker of
   each foot where the simulator marks it visible, with Gaussian noise and a share of gross
   outliers; contact 1 on a foot's flat intervals);
3. corrects every frame with ``torch.optim.LBFGS`` (lr 2, 25 iterations, tolerance 1e-6,
   strong Wolfe: the thesis's settings) on the thesis objective (absolute values and norms,
   per-joint Python-loop kinematics), and with the Levenberg-Marquardt of
   ``gaitnet.pipeline.pose_correction`` in four configurations (the ablation), timing both on
   one thread;
4. prints MPJPE (7 joints, world frame, with the root position) and the foot-point error
   before and after, and the time per frame.

    gaitnet simulate --seed 3 --out /tmp/hpose/s3
    python benchmarks/bench_pose_correction.py /tmp/hpose/s3 [more sessions] [--clean]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

try:
    import torch  # noqa: E402
except ModuleNotFoundError as exc:  # the core install has no PyTorch
    raise SystemExit(f"error: {exc.name} is not installed: pip install -e '.[train]'") from None

from gaitnet.geometry import so3_exp, so3_log  # noqa: E402
from gaitnet.io.trajectory import read_tum  # noqa: E402
from gaitnet.motion import forward_kinematics, from_rest_joints  # noqa: E402
from gaitnet.motion.heading import normalise_heading  # noqa: E402
from gaitnet.motion.onnx_runtime import OnnxPredictor  # noqa: E402
from gaitnet.motion.skeleton import LowerBodySkeleton  # noqa: E402
from gaitnet.pipeline.pelvis_extrinsic import (  # noqa: E402
    estimate_T_PfromC,
    pelvis_from_camera,
    standing_T_WfromP,
)
from gaitnet.pipeline.pose_correction import correct_pose, correct_poses  # noqa: E402
from gaitnet.pipeline.pose_tracking import track_poses  # noqa: E402
from gaitnet.pipeline.pose_types import (  # noqa: E402
    FrameMeasurements,
    PoseCorrectionParams,
    PoseState,
    R_PfromSMPL,
)
from gaitnet.training.scripts import ScriptParser  # noqa: E402

SEVEN = [0, 1, 2, 3, 4, 5, 6]
# Error model of the drawn priors and measurements (stated in docs/pose-correction.md).
PRIOR_JOINT_RAD, PRIOR_ROOT_RAD, PRIOR_TRANS_M = 0.06, 0.03, 0.03
CAMERA_ROT_RAD, CAMERA_POS_M = 0.01, 0.01
FOOT_NOISE_M, OUTLIER_SHARE, OUTLIER_M = 0.015, 0.05, 0.15


def load_truth(session: Path) -> dict[str, np.ndarray]:
    gt = session / "groundtruth"
    j = np.load(gt / "joints.npz")
    t_ns = j["t_ns"] if "t_ns" in j.files else None
    rows = list(csv.DictReader((gt / "feet.csv").open()))
    marker = np.array(
        [[[float(r[f"marker_{s}_{a}"]) for a in "xyz"] for s in ("left", "right")] for r in rows]
    )
    feet_t = np.array([int(r["t_ns"]) for r in rows])
    vis = {}
    for r in csv.DictReader((gt / "marker_pixels.csv").open()):
        vis[(int(r["t_ns"]), r["side"])] = r["visible"] == "1"
    visible = np.array([[vis.get((t, s), False) for s in ("left", "right")] for t in feet_t])
    t_cam, T_WfromC = read_tum(gt / "camera_frames.tum")
    _, T_PfromC_true = read_tum(gt / "mount_frames.tum")
    t_s = feet_t * 1e-9
    contact = np.zeros((len(t_s), 2))
    first_toe_off = np.inf
    for r in csv.DictReader((gt / "events.csv").open()):
        side = 0 if r["side"] == "left" else 1
        contact[:, side] += (t_s >= float(r["flat_start_s"])) & (t_s <= float(r["flat_end_s"]))
        if r["toe_off_s"]:
            first_toe_off = min(first_toe_off, float(r["toe_off_s"]))
    if t_ns is not None and not np.array_equal(t_ns, feet_t):
        raise SystemExit("joints.npz and feet.csv disagree on the frames")
    return {
        "root_orient": j["root_orient"],
        "trans": j["trans"],
        "joint_aa": j["joint_aa"],
        "positions": j["positions"],
        "rest_joints": j["rest_joints"],
        "marker": marker,
        "visible": visible,
        "contact": np.minimum(contact, 1.0),
        "T_WfromC": T_WfromC,
        "T_PfromC_true": T_PfromC_true,
        "t_s": t_s,
        "standing": t_s < first_toe_off - 0.3,
        "t_cam": t_cam,
    }


def noisy_camera(T: np.ndarray, rng: np.random.Generator, noise: float = 1.0) -> np.ndarray:
    out = T.copy()
    out[:, :3, :3] = T[:, :3, :3] @ so3_exp(rng.normal(0, noise * CAMERA_ROT_RAD, (len(T), 3)))
    out[:, :3, 3] += rng.normal(0, noise * CAMERA_POS_M, (len(T), 3))
    return out


def noisy_feet(
    truth: dict[str, np.ndarray], rng: np.random.Generator, noise: float = 1.0
) -> np.ndarray:
    feet = truth["marker"] + rng.normal(0, noise * FOOT_NOISE_M, truth["marker"].shape)
    outlier = rng.random(truth["visible"].shape) < noise * OUTLIER_SHARE
    direction = rng.normal(size=feet.shape)
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    feet += outlier[..., None] * OUTLIER_M * direction
    feet[~truth["visible"]] = np.nan
    return feet


def seven_joints(skel: LowerBodySkeleton, pose: np.ndarray, trans: np.ndarray) -> np.ndarray:
    aa = np.concatenate(
        [pose[..., 3:].reshape(*pose.shape[:-1], 6, 3), np.zeros((*pose.shape[:-1], 2, 3))], axis=-2
    )
    return forward_kinematics(skel, pose[..., :3], trans, aa)[..., SEVEN, :]


# --- the naive baseline: torch L-BFGS on the thesis objective, per-joint Python-loop FK ----------


def _fk_loop(J: torch.Tensor, x: torch.Tensor, t: torch.Tensor) -> list[torch.Tensor]:
    from gaitnet.geometry.torch_rotations import so3_exp_torch

    parents = (-1, 0, 0, 1, 2, 3, 4)
    G, p = [], []
    for j in range(7):
        R = so3_exp_torch(x[3 * j : 3 * j + 3])
        if parents[j] < 0:
            G.append(R)
            p.append(J[0] + t)
        else:
            k = parents[j]
            p.append(p[k] + G[k] @ (J[j] - J[k]))
            G.append(G[k] @ R)
    return p


def lbfgs_correct(
    skel: LowerBodySkeleton, prior: PoseState, m: FrameMeasurements, par: PoseCorrectionParams
) -> tuple[np.ndarray, np.ndarray]:
    J = torch.tensor(np.array(skel.rest_joints[SEVEN]))
    xbar = torch.tensor(np.array(prior.pose))
    x = xbar.clone().requires_grad_(True)
    t = torch.tensor(np.array(prior.trans)).requires_grad_(True)
    root_meas = torch.tensor(so3_log(m.R_WfromP @ R_PfromSMPL))
    p_meas = torch.tensor(np.array(m.p_PinW))
    feet = [(side, torch.tensor(m.foot_W[side])) for side in (0, 1) if m.visible[side]]
    L = {(1, 3): skel.thigh_lengths[0], (2, 4): skel.thigh_lengths[1]}
    L |= {(3, 5): skel.shank_lengths[0], (4, 6): skel.shank_lengths[1]}
    w_init, w_root = 1 / par.sigma_prior_joint_rad, 1 / par.sigma_root_rot_rad
    w_pos, w_foot, w_len = 1 / par.sigma_root_pos_m, 1 / par.sigma_foot_m, 1 / par.sigma_bone_m
    opt = torch.optim.LBFGS(
        [x, t], lr=2, max_iter=25, tolerance_change=1e-6, line_search_fn="strong_wolfe"
    )

    def closure() -> torch.Tensor:
        opt.zero_grad()
        p = _fk_loop(J, x, t)
        cost = w_init * (xbar - x).abs().sum()
        cost = cost + w_root * (root_meas - x[:3]).abs().sum() + w_pos * (p_meas - p[0]).norm()
        for side, f in feet:
            cost = cost + w_foot * (f - p[5 + side]).norm()
        for (a, b), length in L.items():
            cost = cost + w_len * ((p[a] - p[b]).norm() - length).abs()
        cost.backward()
        return cost

    opt.step(closure)
    with torch.no_grad():
        return x.numpy().copy(), t.numpy().copy()


HEADER = (
    "| method | ms/frame wall | ms/frame CPU | MPJPE mm | pelvis mm | ankle seen mm | "
    "ankle unseen mm |\n|---|---|---|---|---|---|---|"
)


def stack(out: list[PoseState]) -> tuple[np.ndarray, np.ndarray]:
    return np.stack([o.pose for o in out]), np.stack([o.trans for o in out])


def timed_per_frame(
    priors: list[PoseState],
    meas: list[FrameMeasurements],
    skel: LowerBodySkeleton,
    par: PoseCorrectionParams,
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """One frame at a time (the predict-correct loop's case): poses and wall / CPU s per frame."""
    c0, w0 = time.process_time(), time.perf_counter()
    out = [correct_pose(p, m, skel, par)[0] for p, m in zip(priors, meas, strict=True)]
    wall, cpu = (time.perf_counter() - w0) / len(out), (time.process_time() - c0) / len(out)
    return *stack(out), wall, cpu


def report(
    skel: LowerBodySkeleton,
    truth: dict[str, np.ndarray],
    idx: np.ndarray,
    name: str,
    pose: np.ndarray,
    trans: np.ndarray,
    wall: float,
    cpu: float,
) -> str:
    j = seven_joints(skel, pose, trans)
    err = np.linalg.norm(j - truth["positions"][idx][:, SEVEN], axis=-1)  # (n, 7)
    vis = truth["visible"][idx]
    ankle = err[:, 5:7]
    return (
        f"| {name} | {wall * 1000:.2f} | {cpu * 1000:.2f} | {err.mean() * 1000:.1f} | "
        f"{err[:, 0].mean() * 1000:.1f} | {ankle[vis].mean() * 1000:.1f} | "
        f"{ankle[~vis].mean() * 1000:.1f} |"
    )


def drawn_priors(
    truth: dict[str, np.ndarray], true_pose: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every frame: the true pose with iid errors (joints, root) and a root position error."""
    n = len(true_pose)
    pose = true_pose.copy()
    pose[:, 3:] += rng.normal(0, PRIOR_JOINT_RAD, (n, 18))
    root = so3_exp(true_pose[:, :3]) @ so3_exp(rng.normal(0, PRIOR_ROOT_RAD, (n, 3)))
    pose[:, :3] = so3_log(root)
    return np.arange(n), pose, truth["trans"] + rng.normal(0, PRIOR_TRANS_M, (n, 3))


def predictor_priors(
    model: Path, truth: dict[str, np.ndarray], true_pose: np.ndarray, horizon: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The committed predictor's pose ``horizon`` frames ahead of 10 true past poses.

    Windows are heading-normalised at their last observed frame (docs/predictor.md) and the
    prediction rotated back; the root position prior extrapolates the last observed velocity.
    """
    n, past = len(true_pose), 10
    idx = np.arange(past + horizon - 1, n)
    windows, yaws = [], []
    for i in idx:
        w = slice(i - horizon - past + 1, i - horizon + 1)
        root_n, _, yaw = normalise_heading(true_pose[w, :3], truth["trans"][w], past - 1)
        windows.append(np.concatenate([root_n, true_pose[w, 3:]], axis=1))
        yaws.append(yaw)
    out = OnnxPredictor(model)(np.stack(windows))[:, past + horizon - 1].astype(np.float64)
    Rz = so3_exp(np.stack([np.zeros(len(idx)), np.zeros(len(idx)), np.array(yaws)], axis=1))
    out[:, :3] = so3_log(Rz @ so3_exp(out[:, :3]))
    last, before = truth["trans"][idx - horizon], truth["trans"][idx - horizon - 1]
    return idx, out, last + horizon * (last - before)


# --- the run -------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("sessions", type=Path, nargs="+", help="simulated session folders")
    ap.add_argument("--lbfgs-frames", type=int, default=40, help="frames for the slow baseline")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--clean", action="store_true", help="noise-free measurements, no outliers")
    ap.add_argument("--model", type=Path, default=Path("models/predictor/dctgcn_walk_small.onnx"))
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    for k, session in enumerate(args.sessions):
        run_session(session, args, np.random.default_rng(args.seed), k == 0)
    return 0


def run_session(session: Path, args: argparse.Namespace, rng: np.random.Generator, lbfgs: bool):
    truth = load_truth(session)
    skel = from_rest_joints(truth["rest_joints"])
    n = len(truth["t_s"])
    true_pose = np.concatenate([truth["root_orient"], truth["joint_aa"][:, :6].reshape(n, 18)], 1)
    noise = 0.0 if args.clean else 1.0

    # 1. extrinsic from the standing frames
    cams = noisy_camera(truth["T_WfromC"], rng, noise)
    feet = noisy_feet(truth, rng, noise)
    st = truth["standing"] & truth["visible"].all(axis=1)
    T_WfromP_stand = standing_T_WfromP(skel, np.median(feet[st], axis=0), cams[st][0])
    ext = estimate_T_PfromC(cams[st], T_WfromP_stand)
    nominal = truth["T_PfromC_true"][0]
    d_rot = np.degrees(np.linalg.norm(so3_log(nominal[:3, :3].T @ ext.T_PfromC[:3, :3])))
    d_pos = np.linalg.norm(nominal[:3, 3] - ext.T_PfromC[:3, 3])
    height = np.ptp(skel.rest_joints[:, 1])
    print(f"\n## session {session.name}: {n} frames, skeleton {height:.2f} m pelvis-to-foot-joint")
    print(f"measurements: {'clean' if args.clean else 'noisy'}; {int(st.sum())} standing frames")
    print(
        f"extrinsic from standing: {d_rot:.2f} deg, {d_pos * 100:.2f} cm from the first true "
        f"mount; spread {np.degrees(ext.spread_rot_rad):.2f} deg, {ext.spread_pos_m * 100:.2f} cm"
    )
    T_WfromP = pelvis_from_camera(cams, ext.T_PfromC)

    # 2. measurements, then priors of each kind, each corrected in every configuration
    meas = [
        FrameMeasurements(T_WfromP[i, :3, :3], T_WfromP[i, :3, 3], feet[i], truth["contact"][i])
        for i in range(n)
    ]
    vis = truth["visible"]
    print(
        f"feet visible: left {vis[:, 0].mean():.0%}, right {vis[:, 1].mean():.0%}; "
        f"contact {truth['contact'].mean():.0%} of foot-frames"
    )
    configs = {
        "LM, thesis objective (eq. 4.8, squared)": PoseCorrectionParams.thesis(),
        "+ constraints (hinge, ROM, fixed lengths)": PoseCorrectionParams.thesis(
            knee_hinge=True, rom_limits=True, fixed_lengths=True
        ),
        "+ robust Cauchy, contact weighting, flat stance feet": PoseCorrectionParams(
            contact_weighting=True, marker_offset=False
        ),
        "+ marker offset (all)": PoseCorrectionParams(contact_weighting=True),
        "all but contact weighting (the default)": PoseCorrectionParams(),
        "the default by scipy L-BFGS-B (correction.solver lbfgs)": PoseCorrectionParams(
            solver="lbfgs"
        ),
        "default without robust loss": PoseCorrectionParams(robust_foot=False),
        "default without flat stance feet": PoseCorrectionParams(flat_foot_contact=False),
    }
    drawn = drawn_priors(truth, true_pose, rng)
    for kind, (idx, prior_pose, prior_trans) in {
        "drawn (iid axis-angle errors)": drawn,
        "the committed predictor, 33 ms ahead": predictor_priors(args.model, truth, true_pose, 1),
        "the committed predictor, 333 ms ahead": predictor_priors(args.model, truth, true_pose, 10),
    }.items():
        print(f"\nprior: {kind}; {len(idx)} frames")
        print(HEADER)
        priors = [PoseState(prior_pose[k], prior_trans[k]) for k in range(len(idx))]
        m = [meas[i] for i in idx]
        rows = [("prior", prior_pose, prior_trans, 0.0, 0.0)]
        for name, par in configs.items():
            pose, trans, wall, cpu = timed_per_frame(priors, m, skel, par)
            rows.append((name, pose, trans, wall, cpu))
        c0, w0 = time.process_time(), time.perf_counter()
        out, info = correct_poses(priors, m, skel, PoseCorrectionParams())
        wall, cpu = (time.perf_counter() - w0) / len(idx), (time.process_time() - c0) / len(idx)
        rows.append(("all, batched over the frames", *stack(out), wall, cpu))
        for row in rows:
            print(report(skel, truth, idx, *row))
        print(
            f"LM iterations (all): median {np.median(info.iterations):.0f}, "
            f"max {info.iterations.max()}"
        )
    closed_loop(args.model, truth, skel, meas)
    if not lbfgs or args.lbfgs_frames <= 0:
        return

    # 3. the naive L-BFGS on evenly spaced frames, against LM on the same frames
    idx, prior_pose, prior_trans = drawn
    sub = np.linspace(0, len(idx) - 1, min(args.lbfgs_frames, len(idx))).astype(int)
    priors = [PoseState(prior_pose[k], prior_trans[k]) for k in sub]
    m = [meas[idx[k]] for k in sub]
    par = PoseCorrectionParams.thesis()
    c0, w0 = time.process_time(), time.perf_counter()
    lb = [lbfgs_correct(skel, p, mm, par) for p, mm in zip(priors, m, strict=True)]
    wall, cpu = (time.perf_counter() - w0) / len(sub), (time.process_time() - c0) / len(sub)
    print(f"\nprior: drawn; the same {len(sub)} evenly spaced frames for both solvers")
    print(HEADER)
    print(report(skel, truth, idx[sub], "prior", prior_pose[sub], prior_trans[sub], 0.0, 0.0))
    lb_pose, lb_trans = np.stack([p for p, _ in lb]), np.stack([t for _, t in lb])
    name = "naive torch L-BFGS, thesis objective"
    print(report(skel, truth, idx[sub], name, lb_pose, lb_trans, wall, cpu))
    pose, trans, wall, cpu = timed_per_frame(priors, m, skel, par)
    name = "LM, thesis objective (eq. 4.8, squared)"
    print(report(skel, truth, idx[sub], name, pose, trans, wall, cpu))
    pose, trans, wall, cpu = timed_per_frame(priors, m, skel, replace(par, solver="lbfgs"))
    name = "scipy L-BFGS-B, thesis objective (squared; correction.solver lbfgs)"
    print(report(skel, truth, idx[sub], name, pose, trans, wall, cpu))


def closed_loop(
    model: Path,
    truth: dict[str, np.ndarray],
    skel: LowerBodySkeleton,
    meas: list[FrameMeasurements],
) -> None:
    """The predict-correct loop over the whole session from 10 standing poses (rest pose at the
    measured pelvis), as the pipeline runs it; MPJPE over the frames after the start."""
    onnx = OnnxPredictor(model)
    past = 10

    def predict(window: np.ndarray) -> np.ndarray:
        return onnx(window[None])[0, past]

    start = []
    for m in meas[:past]:
        root = so3_log(m.R_WfromP @ R_PfromSMPL)
        start.append(PoseState(np.r_[root, np.zeros(18)], m.p_PinW - skel.rest_joints[0]))
    idx = np.arange(past, len(meas))
    print(f"\nclosed loop: predictor → correction, frames {past}..{len(meas) - 1}")
    print(HEADER)
    feet = meas[past:]
    runs = {
        "pelvis only, no feet (default params)": (
            [FrameMeasurements(m.R_WfromP, m.p_PinW) for m in feet],
            PoseCorrectionParams(),
        ),
        "LM, thesis objective (eq. 4.8, squared)": (feet, PoseCorrectionParams.thesis()),
        "all but contact weighting (the default)": (feet, PoseCorrectionParams()),
        "default with contact weighting": (feet, PoseCorrectionParams(contact_weighting=True)),
        "default without flat stance feet": (feet, PoseCorrectionParams(flat_foot_contact=False)),
    }
    for name, (m, par) in runs.items():
        c0, w0 = time.process_time(), time.perf_counter()
        out, priors = track_poses(predict, start, m, skel, par)
        wall, cpu = (time.perf_counter() - w0) / len(idx), (time.process_time() - c0) / len(idx)
        print(report(skel, truth, idx, name, *stack(out), wall, cpu))


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
