"""Screenshots of TensorBoard's real web UI for docs/tensorboard.md, taken with headless Chromium.

    apt-get install -y chromium          # Debian's package
    python docs/tensorboard/make_screenshots.py [--logs /tmp/tb_demo] [--out docs/img]

Runs a tiny 4-job sweep (``mask=zero,lerp model.norm=layer,batch``, 4 epochs, the skeleton figure every epoch), a
second sweep (``model.heads=1,2``) and the same single-run command twice into one log folder (synthetic data, a few
minutes on 2 CPU cores; ``--reuse`` keeps an existing ``--logs``), starts TensorBoard on 127.0.0.1 on that folder's
``tensorboard``, and saves PNGs of the page as a browser draws it (``tb_*.png``, palette-compressed to well under
300 KB each).  The charts are opened with smoothing 0 (``?smoothing=0``; Custom Scalars ``_smoothingWeight=0``): with a
few validation points TensorBoard's default 0.6 draws a curve the values never had.
"""
from __future__ import annotations

import argparse
import base64
import io
import json
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
TINY = ["model.d_model=16", "model.depth=1", "model.heads=2", "data.synthetic.num_clips=10",
        "data.synthetic.min_frames=120", "data.synthetic.max_frames=160", "data.batch_size=8",
        "data.max_eval_windows=8", "data.max_train_windows=64", "trainer.max_epochs=4", "trainer.log_every_n_steps=1",
        "callbacks.progress_bar=null", "callbacks.skeleton_figure.every_n_epochs=1", "calibrate_windows=16", "threads=1"]
#: Closes Time Series' settings pane (open by default on a wide page), giving the cards its room.
CLOSE_SETTINGS = "document.querySelector('[aria-label=\"Close side pane\"]')?.click()"
#: (file, page, window size, what it shows); ``forceSVG``: TensorBoard's charts drawn as SVG (no WebGL in headless)
SHOTS = [
    ("tb_scalars.png", "?forceSVG=true&smoothing=0&tagFilter=%5Eval%2Fl2p_ratio#timeseries", (1280, 860),
     "Time Series, the validation L2P ratios of the sweep (filter ^val/l2p_ratio)"),
    ("tb_landing.png", "?forceSVG=true&smoothing=0#timeseries", (1280, 860), "Time Series as it opens"),
    ("tb_skeleton.png", "?forceSVG=true&tagFilter=%5Eval%2Fskeleton#timeseries", (1280, 1000), "the val/skeleton image cards"),
    ("tb_per_joint.png", "?forceSVG=true&tagFilter=%5Eval%2Fper_joint#timeseries", (1280, 1000), "the val/per_joint image cards"),
    ("tb_hparams.png", "#hparams", (1900, 600), "the HParams table (wide: the metric columns too)"),
    ("tb_custom_scalars.png", "?forceSVG=true#custom_scalars&_smoothingWeight=0", (1280, 860), "Custom Scalars"),
]


def make_logs(logs: Path) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
    common = [*TINY, f"paths.log_dir={logs}"]
    heads = [o for o in common if not o.startswith("model.heads=")]  # (a key set twice: the last value, no sweep)
    runs = [["-m", "mask=zero,lerp", "model.norm=layer,batch", *common], ["-m", "model.heads=1,2", *heads],
            common, common]  # two sweeps, then the single run twice
    for args in runs:
        r = subprocess.run([sys.executable, "train.py", *args], cwd=ROOT, env=env, capture_output=True, text=True)
        if r.returncode:
            sys.exit(r.stderr[-3000:])
        time.sleep(1.1)  # a re-run in the same second would get the version <time>_2: also distinct, less readable


def start_tensorboard(logdir: Path) -> tuple[subprocess.Popen, int]:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    tb = subprocess.Popen([sys.executable, "-m", "tensorboard.main", "--logdir", str(logdir), "--host", "127.0.0.1",
                           "--port", str(port), "--load_fast=true"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(120):
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/data/runs", timeout=5) as r:
                if len(r.read()) > 2:
                    time.sleep(5)  # the data server's first full load
                    return tb, port
        except OSError:
            pass
        time.sleep(1)
    tb.terminate()
    raise RuntimeError("TensorBoard did not start")


class Chromium:
    """Headless Chromium driven over its DevTools pipe (``--remote-debugging-pipe``: commands on fd 3, replies on
    fd 4, NUL-separated JSON), so a page gets real time to load: TensorBoard draws its charts in a web worker,
    which ``--screenshot --virtual-time-budget`` captures before they are drawn."""

    def __init__(self, browser: str, profile: Path):
        cmd_r, self._cmd_w = os.pipe()
        self._res_r, res_w = os.pipe()

        def fds():  # in the child: the pipe ends on fds 3 and 4 (through high fds: either may be 3 or 4 already)
            os.dup2(cmd_r, 200)
            os.dup2(res_w, 201)
            os.dup2(200, 3)
            os.dup2(201, 4)

        self.proc = subprocess.Popen([browser, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                                      "--no-first-run", f"--user-data-dir={profile}", "--remote-debugging-pipe",
                                      "about:blank"], preexec_fn=fds, close_fds=False,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(cmd_r)
        os.close(res_w)
        self._id, self._buf, self._replies = 0, b"", {}
        self._lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]

    def _read(self) -> None:
        while chunk := os.read(self._res_r, 1 << 20):
            self._buf += chunk
            while b"\0" in self._buf:
                msg, self._buf = self._buf.split(b"\0", 1)
                data = json.loads(msg)
                if "id" in data:
                    with self._lock:
                        self._replies[data["id"]] = data

    def call(self, method: str, session: bool = False, **params) -> dict:
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params, **({"sessionId": self.session} if session else {})}
        os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        for _ in range(1200):
            with self._lock:
                if self._id in self._replies:
                    reply = self._replies.pop(self._id)
                    if "error" in reply:
                        raise RuntimeError(f"{method}: {reply['error']}")
                    return reply.get("result", {})
            time.sleep(0.05)
        raise TimeoutError(method)

    def shot(self, url: str, size: tuple[int, int], path: Path, wait: float = 12.0, script: str = "") -> None:
        self.call("Emulation.setDeviceMetricsOverride", session=True, width=size[0], height=size[1],
                  deviceScaleFactor=1, mobile=False)
        self.call("Page.navigate", session=True, url=url)
        time.sleep(wait)
        if script:
            self.call("Runtime.evaluate", session=True, expression=script)
            time.sleep(3)
        png = base64.b64decode(self.call("Page.captureScreenshot", session=True, format="png")["data"])
        img = Image.open(io.BytesIO(png)).convert("RGB")
        img.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
        print(f"{path} ({path.stat().st_size // 1024} KB)")

    def close(self) -> None:
        self.proc.terminate()
        self.proc.wait(timeout=30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--logs", type=Path, default=Path("/tmp/tb_demo"))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img")
    ap.add_argument("--reuse", action="store_true", help="keep an existing --logs instead of training again")
    args = ap.parse_args()
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if not browser:
        sys.exit("no chromium: apt-get install -y chromium")
    if not (args.reuse and (args.logs / "tensorboard").is_dir()):
        shutil.rmtree(args.logs, ignore_errors=True)
        make_logs(args.logs)
    args.out.mkdir(parents=True, exist_ok=True)
    tb, port = start_tensorboard(args.logs / "tensorboard")
    chrome = Chromium(browser, args.logs / "chromium")
    try:
        for name, page, size, _ in SHOTS:
            chrome.shot(f"http://127.0.0.1:{port}/{page}", size, args.out / name, script=CLOSE_SETTINGS)
    finally:
        chrome.close()
        tb.terminate()
        tb.wait(timeout=30)


if __name__ == "__main__":
    main()
