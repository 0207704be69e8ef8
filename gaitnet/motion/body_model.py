"""Rest joints of a subject from an SMPL / SMPL+H / SMPL-X body-model file (thesis sec. 4.2.4).

The thesis computes joint positions with SMPL's joint regressor. For the lower body only the
shape → joint path matters (docs/ecosystem.md):

    J(β) = J_regressor (v_template + shapedirs β),

exactly what ``smplx`` computes before posing (``vertices2joints(J_regressor, v_shaped)``). The
posed joints then follow from :func:`gaitnet.motion.skeleton.forward_kinematics`, which
reproduces smplx's ``batch_rigid_transform`` for the 9 lower-body joints.

So this module reads exactly ``v_template``, ``shapedirs``, ``J_regressor`` and
``kintree_table`` and nothing else: AMASS's extended SMPL+H ``model.npz`` (16 betas, no hand
PCA, which breaks ``smplx.SMPLH``) works, and so do SMPL-X files. Shape components: the first
``min(components, 300)`` columns of ``shapedirs`` (SMPL-X stores its expression basis after
300). All given betas are used, whereas smplx caps them at 10 when a model has fewer than 300
components; AMASS fits 16 betas to its 16-component model, so using all 16 is right for AMASS.
Betas beyond the model's components must be zero, or :class:`BodyModelError` is raised.

Files: ``.npz`` (read without pickles) or ``.pkl``. Pickles are read with an unpickler that
admits only numpy arrays and scipy sparse matrices; a pickle holding chumpy objects (old SMPL
releases) is refused with a message naming the fix, since chumpy fails on numpy >= 1.24.
"""

from __future__ import annotations

import importlib
import pickle
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from gaitnet.errors import InputError
from gaitnet.io.npz import NPZ_READ_ERRORS, open_npz
from gaitnet.motion.skeleton import (
    PARENTS,
    SMPL_JOINT_INDICES,
    LowerBodySkeleton,
    from_rest_joints,
)

__all__ = [
    "REQUIRED_KEYS",
    "SHAPE_SPACE_DIM",
    "BodyModelError",
    "ShapeModel",
    "find_model_file",
    "load_shape_model",
    "lower_body_skeleton",
]

ModelType = Literal["smpl", "smplh", "smplx"]
REQUIRED_KEYS: tuple[str, ...] = ("v_template", "shapedirs", "J_regressor", "kintree_table")
SHAPE_SPACE_DIM = 300
_PREFIX = {"smpl": "SMPL", "smplh": "SMPLH", "smplx": "SMPLX"}
_CHUMPY_FIX = (
    "chumpy does not work with numpy >= 1.24 and is never unpickled here. Convert the model "
    "once to plain arrays: in an environment with chumpy, run smplx's tools/clean_ch.py "
    "(https://github.com/vchoutas/smplx/tree/main/tools) or np.savez the np.asarray() of each "
    "entry; or download the model's .npz release and pass that file"
)


class BodyModelError(InputError):
    """A body-model file is missing, unreadable or incomplete; the message names file and key."""


class _ArraysOnlyUnpickler(pickle.Unpickler):
    """Unpickles numpy arrays and scipy sparse matrices only; refuses chumpy with a fix."""

    _NUMPY = {"ndarray", "dtype", "_reconstruct", "scalar", "_frombuffer"}
    _SPARSE = {"csc_matrix", "csr_matrix", "coo_matrix"}

    def __init__(self, file: Any, path: Path):
        super().__init__(file, encoding="latin1")
        self.path = path

    def find_class(self, module: str, name: str) -> Any:
        if module.split(".")[0] == "chumpy":
            raise BodyModelError(f"{self.path}: the pickle holds chumpy objects. {_CHUMPY_FIX}")
        if module in ("numpy", "numpy.core.multiarray", "numpy._core.multiarray") and (
            name in self._NUMPY
        ):
            source = "numpy" if module == "numpy" else "numpy._core.multiarray"
            return getattr(importlib.import_module(source), name)
        if module.startswith("scipy.sparse") and name in self._SPARSE:
            return getattr(importlib.import_module("scipy.sparse"), name)
        if (module, name) in {("copy_reg", "_reconstructor"), ("copyreg", "_reconstructor")}:
            return importlib.import_module("copyreg")._reconstructor
        if (module, name) in {("__builtin__", "object"), ("builtins", "object")}:
            return object
        if (module, name) == ("_codecs", "encode"):  # bytes in protocol-2 pickles
            return importlib.import_module("_codecs").encode
        raise BodyModelError(
            f"{self.path}: the pickle holds a {module}.{name} object; only numpy arrays and "
            "scipy sparse matrices are loaded (convert the model to .npz)"
        )


def _dense(path: Path, key: str, value: Any) -> np.ndarray:
    if hasattr(value, "toarray"):  # scipy sparse (SMPL's J_regressor)
        value = value.toarray()
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise BodyModelError(f"{path}: key {key!r} is not a numeric array ({exc})") from exc
    if not np.all(np.isfinite(a)):
        raise BodyModelError(f"{path}: key {key!r} contains NaN or inf")
    return a


def _read_arrays(path: Path) -> dict[str, Any]:
    if path.suffix == ".npz":
        with open_npz(path, "an .npz body model", BodyModelError) as data:
            missing = [k for k in REQUIRED_KEYS if k not in data.files]
            if missing:
                raise BodyModelError(
                    f"{path}: missing key(s) {missing}; a body model needs "
                    f"{', '.join(REQUIRED_KEYS)}"
                )
            out = {}
            for k in REQUIRED_KEYS:
                try:
                    out[k] = data[k]
                except ValueError as exc:
                    raise BodyModelError(
                        f"{path}: key {k!r} is a pickled object (e.g. a scipy sparse matrix), "
                        "which is not loaded from .npz; re-save it as a dense array"
                    ) from exc
                except NPZ_READ_ERRORS as exc:
                    raise BodyModelError(f"{path}: key {k!r} is not readable ({exc})") from exc
            return out
    if path.suffix == ".pkl":
        try:
            with open(path, "rb") as handle:
                data = _ArraysOnlyUnpickler(handle, path).load()
        except BodyModelError:
            raise
        except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
            raise BodyModelError(f"{path}: not a readable body-model pickle ({exc})") from exc
        if not isinstance(data, dict):
            raise BodyModelError(f"{path}: expected a dict of arrays, found {type(data).__name__}")
        missing = [k for k in REQUIRED_KEYS if k not in data]
        if missing:
            raise BodyModelError(
                f"{path}: missing key(s) {missing}; a body model needs {', '.join(REQUIRED_KEYS)}"
            )
        return {k: data[k] for k in REQUIRED_KEYS}
    raise BodyModelError(f"{path}: body-model files are .npz or .pkl")


@dataclass(frozen=True, eq=False)
class ShapeModel:
    """The shape → joint part of an SMPL-family model (float64).

    ``v_template`` (V, 3), ``shapedirs`` (V, 3, S) with ``S <= 300`` shape components,
    ``J_regressor`` (J, V) dense, ``parents`` (J,) with ``-1`` at the root.
    """

    path: Path
    v_template: np.ndarray
    shapedirs: np.ndarray
    J_regressor: np.ndarray
    parents: np.ndarray

    @property
    def n_betas(self) -> int:
        return int(self.shapedirs.shape[-1])

    def rest_joints(self, betas: ArrayLike | None = None) -> np.ndarray:
        """``J_regressor (v_template + shapedirs β)`` → all rest joints (J, 3) [m].

        ``betas`` may be shorter than the model's components (the rest count as zero) or
        longer if the extra entries are zero.
        """
        b = np.zeros(0) if betas is None else np.asarray(betas, dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(b)):
            raise BodyModelError(f"{self.path}: betas contain NaN or inf")
        n = min(b.shape[0], self.n_betas)
        if np.any(b[n:] != 0):
            raise BodyModelError(
                f"{self.path}: the model has {self.n_betas} shape components, but betas has "
                f"{b.shape[0]} with non-zero entries beyond {self.n_betas}"
            )
        v_shaped = self.v_template + np.einsum("vck,k->vc", self.shapedirs[:, :, :n], b[:n])
        return self.J_regressor @ v_shaped

    def skeleton(self, betas: ArrayLike | None = None) -> LowerBodySkeleton:
        """The 9-joint lower-body skeleton of shape ``betas``."""
        return from_rest_joints(self.rest_joints(betas)[list(SMPL_JOINT_INDICES)])


def find_model_file(
    model_path: str | Path,
    gender: str = "neutral",
    model_type: ModelType | None = None,
) -> Path:
    """Resolve a model file from a file or a folder.

    Folders are searched in smplx's layout (``{model_type}/{PREFIX}_{GENDER}.npz|.pkl``, also
    directly in the folder) and AMASS's (``[{model_type}/]{gender}/model.npz``); ``.npz`` is
    preferred. Raises :class:`BodyModelError` listing what was tried.
    """
    path = Path(model_path)
    if path.is_file():
        return path
    if not path.is_dir():
        raise BodyModelError(f"{path}: body-model file or folder does not exist")
    g = gender.lower()
    types: Sequence[str] = [model_type] if model_type else list(_PREFIX)
    tried: list[Path] = []
    for t in types:
        if t not in _PREFIX:
            raise BodyModelError(f"unknown model_type {t!r}; use one of {sorted(_PREFIX)}")
        for folder in (path / t, path):
            for ext in ("npz", "pkl"):
                tried.append(folder / f"{_PREFIX[t]}_{g.upper()}.{ext}")
        tried.append(path / t / g / "model.npz")
    tried.append(path / g / "model.npz")
    for candidate in tried:
        if candidate.is_file():
            return candidate
    shown = "\n  ".join(str(p) for p in tried)
    raise BodyModelError(f"{path}: no {g} body model found; looked for\n  {shown}")


def load_shape_model(
    model_path: str | Path,
    gender: str = "neutral",
    model_type: ModelType | None = None,
) -> ShapeModel:
    """Load ``v_template``, ``shapedirs``, ``J_regressor``, ``kintree_table`` of a model.

    ``model_path`` is a model file or a folder (see :func:`find_model_file`). Checks shapes
    and that the lower-body chain is SMPL's (parents of joints 1, 2, 4, 5, 7, 8, 10, 11).
    """
    path = find_model_file(model_path, gender, model_type)
    raw = _read_arrays(path)
    v_template = _dense(path, "v_template", raw["v_template"])
    shapedirs = _dense(path, "shapedirs", raw["shapedirs"])
    J_regressor = _dense(path, "J_regressor", raw["J_regressor"])
    kintree = np.asarray(_dense(path, "kintree_table", raw["kintree_table"]))
    if v_template.ndim != 2 or v_template.shape[1] != 3:
        raise BodyModelError(f"{path}: key 'v_template' must be (V, 3), got {v_template.shape}")
    V = v_template.shape[0]
    if shapedirs.ndim != 3 or shapedirs.shape[:2] != (V, 3):
        raise BodyModelError(f"{path}: key 'shapedirs' must be ({V}, 3, S), got {shapedirs.shape}")
    n_joints = max(SMPL_JOINT_INDICES) + 1
    if J_regressor.ndim != 2 or J_regressor.shape[1] != V or J_regressor.shape[0] < n_joints:
        raise BodyModelError(
            f"{path}: key 'J_regressor' must be (J >= {n_joints}, {V}), got {J_regressor.shape}"
        )
    J = J_regressor.shape[0]
    if kintree.ndim != 2 or kintree.shape[0] != 2 or kintree.shape[1] != J:
        raise BodyModelError(f"{path}: key 'kintree_table' must be (2, {J}), got {kintree.shape}")
    parents = kintree[0].astype(np.int64)
    parents[0] = -1
    smpl_parent = {
        s: SMPL_JOINT_INDICES[p] for s, p in zip(SMPL_JOINT_INDICES, PARENTS, strict=True) if p >= 0
    }
    wrong = {s: int(parents[s]) for s, p in smpl_parent.items() if parents[s] != p}
    if wrong:
        raise BodyModelError(
            f"{path}: key 'kintree_table' is not SMPL's lower-body chain (joint: parent {wrong})"
        )
    shapedirs = np.ascontiguousarray(shapedirs[:, :, :SHAPE_SPACE_DIM])
    return ShapeModel(path, v_template, shapedirs, J_regressor, parents)


def lower_body_skeleton(
    model_path: str | Path,
    gender: str = "neutral",
    betas: ArrayLike | None = None,
    model_type: ModelType | None = None,
) -> LowerBodySkeleton:
    """The lower-body skeleton of a subject: rest joints of ``betas`` (default: mean shape)."""
    return load_shape_model(model_path, gender, model_type).skeleton(betas)
