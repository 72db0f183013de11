#!/usr/bin/env python3
"""Writes a small ONNX model whose outputs are given constants, in a YOLO export's layout, for the
detector's tests and benchmark (Debian's python3-onnx; no network, no weights to download).

    make_yolo_model.py OUT.onnx --input 64x48 --output 1,84,8:values.txt [--output 1,32,16,12:protos.txt]
    make_yolo_model.py OUT.onnx --input 64x64 --topk        (a YOLOv10 NMS-free export's TopK layer)

Each --output is a shape and a text file of its row-major values (whitespace separated); the model
computes it from the image as Conv(GlobalAveragePool(images)) with zero weights and the values as
the bias, reshaped: the output does not depend on the image, yet the graph reads it, as a real
network does. Input: `images`, [1, 3, H, W] float (--input WxH)."""
import argparse
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper


def constant_branch(name, shape, values, pooled, nodes, inits):
    count = int(np.prod(shape))
    if values.size != count:
        sys.exit(f"make_yolo_model: {name}: {values.size} values for shape {shape} ({count})")
    w = numpy_helper.from_array(np.zeros((count, 3, 1, 1), np.float32), f"{name}_w")
    b = numpy_helper.from_array(values.astype(np.float32), f"{name}_b")
    s = numpy_helper.from_array(np.array(shape, np.int64), f"{name}_shape")
    inits += [w, b, s]
    nodes.append(helper.make_node("Conv", [pooled, w.name, b.name], [f"{name}_flat"], kernel_shape=[1, 1]))
    nodes.append(helper.make_node("Reshape", [f"{name}_flat", s.name], [name]))
    return helper.make_tensor_value_info(name, TensorProto.FLOAT, list(shape))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--input", default="64x64")
    ap.add_argument("--output", action="append", default=[])
    ap.add_argument("--topk", action="store_true")
    a = ap.parse_args()
    w, h = (int(v) for v in a.input.split("x"))
    images = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, h, w])
    nodes = [helper.make_node("GlobalAveragePool", ["images"], ["pooled"])]
    inits, outputs = [], []
    if a.topk:
        s = numpy_helper.from_array(np.array([1, 3], np.int64), "flat_shape")
        k = numpy_helper.from_array(np.array([1], np.int64), "k")
        inits += [s, k]
        nodes.append(helper.make_node("Reshape", ["pooled", "flat_shape"], ["flat"]))
        nodes.append(helper.make_node("TopK", ["flat", "k"], ["top_values", "top_indices"], axis=1))
        outputs.append(helper.make_tensor_value_info("top_values", TensorProto.FLOAT, [1, 1]))
        outputs.append(helper.make_tensor_value_info("top_indices", TensorProto.INT64, [1, 1]))
    for k, spec in enumerate(a.output):
        shape_text, path = spec.split(":", 1)
        shape = [int(v) for v in shape_text.split(",")]
        values = np.loadtxt(path, dtype=np.float32).reshape(-1)
        outputs.append(constant_branch(f"output{k}", shape, values, "pooled", nodes, inits))
    graph = helper.make_graph(nodes, "yolo_constant", [images], outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 12)], producer_name="dqo_map tests")
    model.ir_version = 7
    onnx.checker.check_model(model)
    onnx.save(model, a.out)


if __name__ == "__main__":
    main()
