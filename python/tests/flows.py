"""The flows of a list of jobs in one process (imports and weights loaded once), for the
comparison with pins in tests/python_port.rs:

    python flows.py JOBS.json

Each job is one of
    {"export": WEIGHTS, "iters": N, "out": F.onnx}             export to ONNX (dynamic size)
    {"weights": WEIGHTS, "img1": A, "img2": B, "iters": N, "out": F.flo}    PyTorch
        (with "float64": true, in double precision: the reference both float32 forms are
        measured against)
    {"onnx": F.onnx, "img1": A, "img2": B, "out": F.flo}       ONNX Runtime
and prints one JSON line per job with its seconds.
"""

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import torch  # noqa: E402

from pins_mms.io import read_image, write_flo  # noqa: E402
from pins_mms.model import FlowModel  # noqa: E402
from pins_mms.onnx_export import export_onnx, run_onnx  # noqa: E402
from pins_mms.weights import load  # noqa: E402


def main(path: str) -> None:
    models = {}
    for job in json.loads(Path(path).read_text()):
        t = time.perf_counter()
        if "export" in job:
            export_onnx(job["export"], job["out"], job["iters"])
        else:
            a, b = read_image(job["img1"])[None], read_image(job["img2"])[None]
            if "onnx" in job:
                flow = run_onnx(job["onnx"], a, b)[0]
            else:
                dtype = torch.float64 if job.get("float64") else torch.float32
                key = (job["weights"], dtype)
                if key not in models:
                    models[key] = load(job["weights"]).to(dtype)
                with torch.inference_mode():
                    model = FlowModel(models[key], job["iters"])
                    ta, tb = (torch.from_numpy(x).to(dtype) for x in (a, b))
                    flow = model(ta, tb)[0].float().numpy()
            write_flo(job["out"], flow)
        print(json.dumps({"out": job["out"], "seconds": round(time.perf_counter() - t, 3)}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1])
