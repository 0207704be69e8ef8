"""Fuzz the onnxruntime wrapper (gaitnet.motion.onnx_runtime.OnnxPredictor): inputs and files.

Generated broken inputs (non-finite values anywhere, values beyond float32, wrong ranks, shapes
and dtypes, empty batches, ragged lists) and broken model files (missing, a folder, empty,
garbage, truncated, bit flips, foreign graphs) must each raise a one-line
:class:`~gaitnet.errors.InputError` naming the model file (and the input); the committed model
still answers valid input, and never with a non-finite number.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import pytest
from oneline import assert_one_line_message
from onnx import TensorProto, helper

from gaitnet.errors import InputError
from gaitnet.motion.onnx_runtime import OnnxInputError, OnnxPredictor

MODEL = Path(__file__).parents[1] / "models" / "predictor" / "dctgcn_walk_small.onnx"
pytestmark = [
    pytest.mark.filterwarnings("error::RuntimeWarning"),
    pytest.mark.filterwarnings("error::UserWarning"),
]


@pytest.fixture(scope="module")
def predictor() -> OnnxPredictor:
    return OnnxPredictor(MODEL)


def _valid(rng: np.random.Generator, batch: int = 3) -> np.ndarray:
    return rng.normal(scale=0.3, size=(batch, 10, 21))


# ---------------------------------------------------------------------------- inputs


@pytest.mark.parametrize("seed", range(12))
def test_non_finite_input_anywhere_is_refused(predictor: OnnxPredictor, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = _valid(rng, batch=int(rng.integers(1, 6)))
    index = tuple(int(rng.integers(0, n)) for n in x.shape)
    x[index] = [np.nan, np.inf, -np.inf, 1e39][seed % 4]  # 1e39 is inf as float32
    dtype = np.float64 if seed % 4 == 3 else [np.float32, np.float64, np.float16][seed % 3]
    with pytest.raises(OnnxInputError) as exc:
        predictor(x.astype(dtype) if seed % 4 != 3 else x)
    assert_one_line_message(exc, str(MODEL), "past_poses", f"index {index}", error_type=InputError)


BAD_INPUTS = {
    "rank_2": np.zeros((10, 21)),
    "rank_4": np.zeros((1, 1, 10, 21)),
    "scalar": np.float32(1.0),
    "n_past_9": np.zeros((2, 9, 21)),
    "n_past_11": np.zeros((2, 11, 21)),
    "nodes_20": np.zeros((2, 10, 20)),
    "nodes_63": np.zeros((2, 10, 63)),
    "empty_batch": np.zeros((0, 10, 21), np.float32),
    "complex": np.zeros((1, 10, 21), np.complex64),
    "bool": np.zeros((1, 10, 21), bool),
    "strings": np.full((1, 10, 21), "0.5"),
    "objects": np.full((1, 10, 21), None, dtype=object),
    "datetime": np.zeros((1, 10, 21), "datetime64[s]"),
}


@pytest.mark.parametrize("name", sorted(BAD_INPUTS))
def test_wrong_rank_shape_or_dtype_is_refused(predictor: OnnxPredictor, name: str) -> None:
    with pytest.raises(OnnxInputError) as exc:
        predictor(BAD_INPUTS[name])
    assert_one_line_message(exc, str(MODEL), "past_poses", error_type=InputError)


def test_ragged_list_is_refused(predictor: OnnxPredictor) -> None:
    ragged = [[[0.0] * 21] * 10, [[0.0] * 21] * 9]
    with pytest.raises(OnnxInputError) as exc:
        predictor(ragged)
    assert_one_line_message(exc, str(MODEL), "past_poses", error_type=InputError)


@pytest.mark.parametrize("kind", ["float32", "float64", "float16", "int64", "list"])
def test_valid_inputs_still_pass(predictor: OnnxPredictor, kind: str) -> None:
    x = _valid(np.random.default_rng(1), batch=4)
    reference = predictor(x.astype(np.float32))
    given = x.tolist() if kind == "list" else x.astype(kind)
    out = predictor(given)
    assert out.shape == (4, 20, 21) and out.dtype == np.float32 and np.all(np.isfinite(out))
    if kind in ("float64", "list"):
        np.testing.assert_array_equal(out, reference)
    assert predictor.predict_future(given).shape == (4, 10, 21)


# ---------------------------------------------------------------------------- files


def _graph_model(path: Path, inputs, nodes, outputs) -> Path:
    graph = helper.make_graph(nodes, "foreign", inputs, outputs)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
    model.ir_version = 9
    onnx.save(model, path)
    return path


def _file_cases(folder: Path) -> dict[str, Path]:
    good = MODEL.read_bytes()
    cases = {"missing": folder / "none.onnx", "folder": folder}

    def write(name: str, content: bytes) -> None:
        cases[name] = folder / f"{name}.onnx"
        cases[name].write_bytes(content)

    write("empty", b"")
    write("garbage", b"this is not a protobuf \x00\xff" * 20)
    write("truncated", good[: len(good) // 2])
    flipped = bytearray(good)
    for i in np.random.default_rng(3).integers(0, 400, size=60):  # the graph's header
        flipped[i] ^= 0xA5
    write("bitflips", bytes(flipped))
    cases["int_input"] = _graph_model(
        folder / "int_input.onnx",
        [helper.make_tensor_value_info("x", TensorProto.INT64, ["batch", 10, 21])],
        [helper.make_node("Identity", ["x"], ["y"])],
        [helper.make_tensor_value_info("y", TensorProto.INT64, ["batch", 10, 21])],
    )
    cases["two_inputs"] = _graph_model(
        folder / "two_inputs.onnx",
        [helper.make_tensor_value_info(n, TensorProto.FLOAT, ["batch", 10, 21]) for n in "ab"],
        [helper.make_node("Add", ["a", "b"], ["y"])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["batch", 10, 21])],
    )
    cases["rank_2_input"] = _graph_model(
        folder / "rank_2.onnx",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", 21])],
        [helper.make_node("Identity", ["x"], ["y"])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["batch", 21])],
    )
    return cases


FILE_CASES = ["missing", "folder", "empty", "garbage", "truncated", "bitflips", "int_input",
              "two_inputs", "rank_2_input"]  # fmt: skip


@pytest.fixture(scope="module")
def file_cases(tmp_path_factory) -> dict[str, Path]:
    return _file_cases(tmp_path_factory.mktemp("onnx"))


@pytest.mark.parametrize("case", FILE_CASES)
def test_broken_model_files_are_one_line(file_cases: dict[str, Path], case: str) -> None:
    with pytest.raises(OnnxInputError) as exc:
        predictor = OnnxPredictor(file_cases[case])
        predictor(np.zeros((1, 10, 21), np.float32))  # a file that loads must still fail here
    assert_one_line_message(exc, str(file_cases[case]), error_type=InputError)


def test_a_model_that_outputs_inf_is_refused(tmp_path: Path) -> None:
    """Finite input, non-finite output (a broken model): refused, not passed on."""
    zero = helper.make_tensor("zero", TensorProto.FLOAT, [1], [0.0])
    path = _graph_model(
        tmp_path / "div0.onnx",
        [helper.make_tensor_value_info("past_poses", TensorProto.FLOAT, ["batch", 10, 21])],
        [
            helper.make_node("Constant", [], ["z"], value=zero),
            helper.make_node("Div", ["past_poses", "z"], ["poses"]),
        ],  # fmt: skip
        [helper.make_tensor_value_info("poses", TensorProto.FLOAT, ["batch", 10, 21])],
    )
    with pytest.raises(OnnxInputError) as exc:
        OnnxPredictor(path)(np.ones((2, 10, 21), np.float32))
    assert_one_line_message(exc, str(path), "output 'poses' is not finite", error_type=InputError)


def test_a_model_that_differs_from_its_sidecar_sha256_is_refused(tmp_path: Path) -> None:
    """One byte of the model changed (its weights: onnxruntime would load it): the SHA-256 its
    sidecar records no longer matches, and the file is refused before it is loaded."""
    path = tmp_path / MODEL.name
    path.write_bytes(MODEL.read_bytes())
    sidecar = tmp_path / f"{MODEL.stem}.json"
    sidecar.write_bytes(MODEL.with_suffix(".json").read_bytes())
    OnnxPredictor(path)  # the intact copy with its sidecar loads
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))
    with pytest.raises(OnnxInputError) as exc:
        OnnxPredictor(path)
    assert_one_line_message(exc, str(path), str(sidecar), "SHA-256", error_type=InputError)


@pytest.mark.parametrize("threads", [-1, 1.5, True, 10**6])
def test_bad_thread_counts(threads) -> None:
    with pytest.raises(OnnxInputError) as exc:
        OnnxPredictor(MODEL, threads=threads)
    assert_one_line_message(exc, "threads", error_type=InputError)
