#!/usr/bin/env python3
"""Writes a tiny ONNX "detector" whose output is a table given on the command line.

The dnn detector's tests need a model whose answer they know. The graph cuts an N x K patch out of
the input image, multiplies it by zero and adds the constant table: the output depends on the
input, so OpenCV really runs the graph, yet always equals the table.

  ssd:  output [1, 1, N, 7]   rows: image_id, class_id, score, x1, y1, x2, y2 (normalised)
  yolo: output [N, K]         rows: cx, cy, w, h, objectness, class scores...

Usage: make_tiny_detector.py OUT.onnx {ssd|yolo} HEIGHT WIDTH ROW [ROW ...]
HEIGHT x WIDTH is the network's input size, at least N x K. Each ROW is comma-separated numbers;
all rows have the same length. Opset 11 and only Slice, Mul, Add and Reshape: the ONNX importer of
OpenCV 4.6 runs these (its Add does not broadcast a [1, 1, 1, 1] tensor against a table, so the
patch has the table's shape).
"""
import sys

import onnx
from onnx import TensorProto, helper


def constant(name, data_type, dims, values):
    return helper.make_node("Constant", [], [name], value=helper.make_tensor(name + "_value", data_type, dims, values))


def main(argv):
    if len(argv) < 6 or argv[2] not in ("ssd", "yolo"):
        sys.stderr.write(__doc__)
        return 2
    out, layout, height, width = argv[1], argv[2], int(argv[3]), int(argv[4])
    rows = [[float(v) for v in row.split(",")] for row in argv[5:]]
    n, k = len(rows), len(rows[0])
    if any(len(r) != k for r in rows):
        sys.stderr.write("make_tiny_detector: rows of different lengths\n")
        return 2
    if layout == "ssd" and k != 7:
        sys.stderr.write("make_tiny_detector: ssd rows have 7 numbers\n")
        return 2
    if n > height or k > width:
        sys.stderr.write("make_tiny_detector: the input must be at least N x K pixels\n")
        return 2

    table_shape = [1, 1, n, k]
    nodes = [
        constant("starts", TensorProto.INT64, [4], [0, 0, 0, 0]),
        constant("ends", TensorProto.INT64, [4], table_shape),
        helper.make_node("Slice", ["image", "starts", "ends"], ["patch"]),
        constant("zero", TensorProto.FLOAT, [1], [0.0]),
        helper.make_node("Mul", ["patch", "zero"], ["nothing"]),
        constant("table", TensorProto.FLOAT, table_shape, [v for r in rows for v in r]),
    ]
    if layout == "ssd":
        out_shape = table_shape
        nodes.append(helper.make_node("Add", ["nothing", "table"], ["detections"]))
    else:
        out_shape = [n, k]
        nodes.append(helper.make_node("Add", ["nothing", "table"], ["detections_4d"]))
        nodes.append(constant("out_shape", TensorProto.INT64, [2], out_shape))
        nodes.append(helper.make_node("Reshape", ["detections_4d", "out_shape"], ["detections"]))

    graph = helper.make_graph(
        nodes, "tiny_detector",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, height, width])],
        [helper.make_tensor_value_info("detections", TensorProto.FLOAT, out_shape)])
    model = helper.make_model(graph, producer_name="fogmap-tests", opset_imports=[helper.make_opsetid("", 11)])
    model.ir_version = 6  # the IR of opset 11
    onnx.checker.check_model(model)
    onnx.save(model, out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
