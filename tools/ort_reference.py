#!/usr/bin/env python3
"""ONNX Runtime beside `neusample bench`, from one run on one machine.

Runs `neusample bench --json` (or reads a saved report), then times the bench's networks (its
`library.networks`: the neural material's decoder and the samplers' MLPs, ReLU between
layers) as ONNX Gemm chains in ONNX Runtime's CPU provider on one thread, at the bench's batch
sizes, and prints them beside the runtime's figures from the same run:

    neural material decoder 14→64→64→64→3     N=64: eval 250  kernel 230  ORT 300 (−call 260)

ORT's time includes its per-call overhead through Python; the `−call` column subtracts the
time of a 1→1 model at the same batch, an estimate of what a C++ caller would see.

    python3 tools/ort_reference.py [--neusample target/release/neusample] [--report R.json]
            [--json OUT.json]

Needs `onnxruntime`, `onnx` and `numpy` (pip). Exits 3 when they are missing.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time


def need_ort():
    try:
        import numpy  # noqa: F401
        import onnx  # noqa: F401
        import onnxruntime  # noqa: F401
    except ImportError as e:
        print(f"ort_reference: {e.name} is not installed (pip install onnxruntime onnx numpy)",
              file=sys.stderr)
        sys.exit(3)


def model(widths, seed=0):
    """An MLP as Gemm (+ Relu between layers) nodes, fixed pseudo-random weights."""
    import numpy as np
    from onnx import TensorProto, helper, numpy_helper

    rng = np.random.default_rng(seed)
    nodes, inits = [], []
    prev = "x"
    for k, (i, o) in enumerate(zip(widths[:-1], widths[1:])):
        w = (rng.random((i, o), dtype=np.float32) - 0.5).astype(np.float32)
        b = (rng.random((o,), dtype=np.float32) - 0.5).astype(np.float32)
        inits += [numpy_helper.from_array(w, f"w{k}"), numpy_helper.from_array(b, f"b{k}")]
        out = "y" if k == len(widths) - 2 else f"h{k}"
        gemm = out if out == "y" else f"g{k}"
        nodes.append(helper.make_node("Gemm", [prev, f"w{k}", f"b{k}"], [gemm]))
        if out != "y":
            nodes.append(helper.make_node("Relu", [gemm], [out]))
        prev = out
    graph = helper.make_graph(
        nodes,
        "mlp",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["n", widths[0]])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["n", widths[-1]])],
        inits,
    )
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 8
    return m.SerializeToString()


def session(widths):
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    return ort.InferenceSession(model(widths), so, providers=["CPUExecutionProvider"])


def ns_per_point(widths, n, passes=7, pass_seconds=0.15):
    """Median over `passes` of ns per point, `n` points per call, bound input and output."""
    import numpy as np
    import onnxruntime as ort

    s = session(widths)
    x = ort.OrtValue.ortvalue_from_numpy(
        np.random.default_rng(1).random((n, widths[0]), dtype=np.float32) - 0.5)
    y = ort.OrtValue.ortvalue_from_numpy(np.zeros((n, widths[-1]), dtype=np.float32))
    io = s.io_binding()
    io.bind_ortvalue_input("x", x)
    io.bind_ortvalue_output("y", y)
    for _ in range(50):
        s.run_with_iobinding(io)
    per = []
    for _ in range(passes):
        calls, t0 = 0, time.perf_counter()
        while True:
            for _ in range(20):
                s.run_with_iobinding(io)
            calls += 20
            dt = time.perf_counter() - t0
            if dt >= pass_seconds:
                break
        per.append(dt * 1e9 / (calls * n))
    return statistics.median(per)


def widths_of(arrows):
    return [int(w) for w in arrows.split("→")]


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--neusample", default="target/release/neusample",
                    help="the neusample binary (default: %(default)s)")
    ap.add_argument("--report", help="a saved `neusample bench --json` report instead of a run")
    ap.add_argument("--json", help="also write the figures here")
    a = ap.parse_args()
    need_ort()
    import onnxruntime as ort

    if a.report:
        with open(a.report) as f:
            report = json.load(f)
    else:
        if not os.access(a.neusample, os.X_OK):
            sys.exit(f"ort_reference: {a.neusample} is not an executable "
                     "(cargo build --release -p neusample-precompute --bin neusample)")
        out = subprocess.run([a.neusample, "bench", "--json"], check=True,
                             capture_output=True, text=True).stdout
        report = json.loads(out)

    lib = report["library"]
    batches = [n for n, _ in lib["runtime_decoder"]["ns_per_point"]]
    call = {n: ns_per_point([1, 1], n) for n in batches}
    rows = []
    for net in lib["networks"]:
        w = widths_of(net["widths"])
        rows.append({
            "network": net["network"],
            "widths": net["widths"],
            "ort_ns": {n: ns_per_point(w, n) for n in batches},
            "gemm_ns": dict(net["ns_per_point"]),
        })
    eval_ns = dict(report["neural_material"]["eval_batch_ns"])
    kernel_ns = dict(lib["runtime_decoder"]["ns_per_point"])
    machine = report.get("machine", {})

    print(f"ONNX Runtime {ort.__version__} (CPU provider, 1 thread) beside neusample bench, "
          f"ns per point, medians")
    print(f"machine: {machine.get('cpu', cpu_model())}; neusample's instruction set: "
          f"{report['isa']}; {lib['library']}")
    print(f"ORT's call overhead through Python (a 1→1 model): "
          + ", ".join(f"N={n}: {call[n]:.0f}" for n in batches))
    for r in rows:
        print(f"\n{r['network']} ({r['widths']})")
        for n in batches:
            ort_ns = r["ort_ns"][n]
            line = f"  N={n:<5} ORT {ort_ns:7.0f} (−call {max(ort_ns - call[n], 0):5.0f})" \
                   f"   gemm library {r['gemm_ns'][n]:6.0f}"
            if r is rows[0]:
                line += f"   neusample: decoder kernel {kernel_ns[n]:5.0f}, " \
                        f"material eval {eval_ns[n]:5.0f} " \
                        f"({eval_ns[n] / kernel_ns[n]:.2f}× kernel, " \
                        f"{eval_ns[n] / ort_ns:.2f}× ORT)"
            print(line)
    if a.json:
        with open(a.json + ".tmp", "w") as f:
            json.dump({"onnxruntime": ort.__version__, "call_overhead_ns": call,
                       "networks": rows, "bench": report}, f, indent=1)
        os.replace(a.json + ".tmp", a.json)


if __name__ == "__main__":
    main()
