"""``report.html`` of ``diagnose --report`` and ``identify --report`` rendered in headless
Chromium: no console error, every figure decoded (naturalWidth > 0) and visible (its part of
a screenshot is not blank), one file that still shows everything when copied elsewhere.

The browser is driven over the Chrome DevTools protocol on ``--remote-debugging-pipe`` (file
descriptors 3 and 4, NUL-separated JSON) with the standard library only. Skipped only when no
Chromium is installed; CI installs Debian's ``chromium`` (``.ci/run``).
"""

from __future__ import annotations

import base64
import fcntl
import io
import json
import os
import re
import select
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = next((p for p in (os.environ.get("CDPRID_CHROMIUM"), shutil.which("chromium"),
                             shutil.which("chromium-browser"), shutil.which("google-chrome"))
                 if p), None)
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="no chromium installed (CI "
                                    "installs it: apt-get install chromium)")


class Browser:
    """A headless Chromium page driven over ``--remote-debugging-pipe``."""

    def __init__(self, profile: Path):
        cmd_r, self._cmd_w = os.pipe()  # we write commands, Chromium reads fd 3
        self._out_r, out_w = os.pipe()  # Chromium writes fd 4, we read
        high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (cmd_r, out_w)]  # not 3 or 4
        os.close(cmd_r)
        os.close(out_w)
        cmd_r, out_w = high

        # bash moves the pipe ends to fds 3 and 4 (no preexec_fn: JAX's at-fork hook
        # warns in a forked child of a multithreaded process)
        move = f'exec "$0" "$@" 3<&{cmd_r} 4>&{out_w} {cmd_r}<&- {out_w}>&-'
        self.proc = subprocess.Popen(
            [shutil.which("bash") or "/bin/bash", "-c", move, CHROMIUM, "--headless",
             "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", "--hide-scrollbars", "--remote-debugging-pipe",
             f"--user-data-dir={profile}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            pass_fds=(cmd_r, out_w))
        os.close(cmd_r)
        os.close(out_w)
        self._buf, self._id, self.events = b"", 0, []
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target,
                                 flatten=True)["sessionId"]
        for domain in ("Page", "Runtime", "Log"):
            self.call(f"{domain}.enable", session=True)

    def _read(self, timeout: float) -> dict:
        end = time.monotonic() + timeout
        while b"\0" not in self._buf:
            left = end - time.monotonic()
            if left <= 0 or not select.select([self._out_r], [], [], left)[0]:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self._out_r, 1 << 20)
            if not chunk:
                raise ConnectionError("chromium closed the pipe")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def call(self, method: str, session: bool = False, timeout: float = 30.0, **params):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        while True:
            m = self._read(timeout)
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m["result"]
            self.events.append(m)

    def load(self, url: str, timeout: float = 30.0) -> None:
        """Navigate to ``url`` and wait for its load event (events of earlier pages dropped)."""
        self.events = []
        self.call("Page.navigate", session=True, url=url)
        end = time.monotonic() + timeout
        while not any(e.get("method") == "Page.loadEventFired" for e in self.events):
            self.events.append(self._read(max(end - time.monotonic(), 0.01)))

    def evaluate(self, expression: str):
        r = self.call("Runtime.evaluate", session=True, expression=expression,
                      returnByValue=True, awaitPromise=True)
        return r["result"]["value"]

    def errors(self) -> list[str]:
        """Console errors, uncaught exceptions and error log entries seen so far."""
        out = []
        for e in self.events:
            m, p = e.get("method"), e.get("params", {})
            if m == "Runtime.exceptionThrown":
                out.append(p["exceptionDetails"].get("text", "exception"))
            elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                out.append(str(p.get("args")))
            elif m == "Log.entryAdded" and p["entry"].get("level") == "error":
                out.append(p["entry"].get("text", ""))
        return out

    def screenshot(self, clip: dict | None = None) -> np.ndarray:
        params = {"format": "png", "captureBeyondViewport": True}
        if clip:
            params["clip"] = {**clip, "scale": 1}
        png = base64.b64decode(self.call("Page.captureScreenshot", session=True, **params)["data"])
        import matplotlib.image

        return matplotlib.image.imread(io.BytesIO(png), format="png")

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=5)
        except (TimeoutError, ConnectionError, RuntimeError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._cmd_w)
        os.close(self._out_r)


FIGURES_JS = """JSON.stringify(Array.from(document.images).map(i => {
  const r = i.getBoundingClientRect();
  return {alt: i.alt, complete: i.complete, w: i.naturalWidth, h: i.naturalHeight,
          x: r.left + window.scrollX, y: r.top + window.scrollY, cw: r.width, ch: r.height};
}))"""


def not_blank(pixels: np.ndarray) -> bool:
    """More than 1 % of the pixels differ from the most common colour (the background)."""
    rgb = np.round(pixels[..., :3] * 255).astype(int)
    flat = rgb.reshape(-1, 3) @ np.array([65536, 256, 1])
    values, counts = np.unique(flat, return_counts=True)
    return 1.0 - counts.max() / flat.size > 0.01


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    """One headless Chromium for the module's pages."""
    b = Browser(tmp_path_factory.mktemp("chromium-profile"))
    b.call("Emulation.setDeviceMetricsOverride", session=True, width=1200, height=900,
           deviceScaleFactor=1, mobile=False)
    yield b
    b.close()


def check_page(b: Browser, html: Path) -> dict:
    """Load ``html`` in Chromium; assert no error and every figure visible; return facts."""
    text = html.read_text(encoding="utf-8")
    assert not re.search(r"<script|<link|<iframe|src=\"(?!data:)|url\(", text, re.I), \
        "report.html must not load anything (scripts, styles, images by URL)"
    b.load(html.resolve().as_uri())
    figs = json.loads(b.evaluate(FIGURES_JS))
    assert figs, "the report has no figure"
    for f in figs:
        assert f["complete"] and f["w"] > 0 and f["h"] > 0, f"figure not decoded: {f['alt']}"
        assert f["cw"] > 100 and f["ch"] > 50, f"figure not shown: {f['alt']}"
        shot = b.screenshot({"x": f["x"], "y": f["y"], "width": f["cw"], "height": f["ch"]})
        assert not_blank(shot), f"figure blank on screen: {f['alt']}"
    page = b.screenshot()
    assert not_blank(page)
    title = b.evaluate("document.title")
    verdict = b.evaluate("document.querySelector('.verdict').innerText")
    first = b.evaluate("document.body.children[1].className")
    footer = b.evaluate("document.querySelector('footer').innerText")
    assert b.errors() == [], b.errors()
    return {"figures": figs, "title": title, "verdict": verdict, "first": first,
            "footer": footer, "text": text}


# ----------------------------------------------------------------------------- fixtures


def _diagnosis_with_findings(episodes: bool):
    """A DiagnosisResult with a finding, a competing model, an unexplained item and (with
    ``episodes``) two episodes: the report's inputs, not a diagnosis run."""
    from cdprid.diagnosis import DiagnosisResult, Finding

    rng = np.random.default_rng(3)
    t = np.arange(0, 20, 0.02)
    explained = np.zeros((len(t), 6))
    explained[:, 0] = 0.8 * np.sin(2 * np.pi * 0.5 * t)
    ext = 0.2 * rng.standard_normal((len(t), 6))
    par = {"m": {"value": 6.3, "std": 0.003, "rel_std_percent": 0.05}}
    f = Finding("time_delay", {"delay_s": -0.005}, {"delay_s": [-0.0052, -0.0048]}, ["x"],
                0.97, 0.72, 1e-12, 2050.0, 1e-5)
    res = DiagnosisResult(
        base_parameters=par, base_residual_rms=[0.5] * 6, base_heldout_rms=0.36,
        findings=[f], extended_parameters=par, extended_heldout_rms=0.27, ranking=[],
        info={"heldout": "blocked 5-fold CV", "competing_models_tried": 1,
              "train_until": None},
        arrays={"t": t, "residual_base": ext + explained, "residual_extended": ext,
                "use": np.ones(len(t), bool), "train": np.ones(len(t), bool)},
        unexplained=[{"where": "force along z", "size": 0.26,
                      "correlates_with": "its own past", "p_value": 3e-54}],
        notes=["a note <with markup> & an ampersand"],
        competing=[{"replaces": "time_delay", "by": "x", "parameters": {"x": {"k": 1.0}},
                    "heldout_force_rms_N": 0.272, "relative_difference": 0.004,
                    "p_worse": 0.3}])
    if episodes:
        object.__setattr__(res, "episodes", [{"start_s": 3.0, "end_s": 5.0, "kind": "push"},
                                             {"start_s": 11.0, "end_s": 12.5, "kind": "slack"}])
    return res


@needs_chromium
@pytest.mark.parametrize("episodes", [False, True])
def test_diagnosis_report_renders(browser, tmp_path, episodes):
    """A diagnosis with a finding (and episodes): verdict first, every figure visible, no
    console error; copied alone elsewhere it still shows every figure."""
    from cdprid.report import write_diagnosis_html

    res = _diagnosis_with_findings(episodes)
    out = tmp_path / "rep"
    out.mkdir()
    made = {"command": "cdprid diagnose data --report rep", "version": "9.9"}
    html = write_diagnosis_html(res, out, "data", made)
    copy = tmp_path / "elsewhere" / "report.html"
    copy.parent.mkdir()
    shutil.copy(html, copy)
    facts = check_page(browser, copy)
    assert facts["first"].startswith("verdict")
    assert "1 finding(s): time_delay" in facts["verdict"]
    assert "cdprid diagnose data --report rep" in facts["footer"] and "9.9" in facts["footer"]
    assert "&lt;with markup&gt; &amp; an ampersand" in facts["text"]
    assert "25.8 % lower" in facts["text"]  # the finding's held-out gain 0.97 -> 0.72
    assert ("episode: push" in facts["text"]) is False  # in the figure, not the text
    assert ("coloured bands, episodes" in facts["text"]) == episodes


@needs_chromium
def test_identify_report_of_the_example(browser, tmp_path):
    """`cdprid identify --report` of the package's example dataset renders in Chromium."""
    from cdprid.cli import main
    from cdprid.data import write_sample

    ds = write_sample(tmp_path / "sample")
    rc = main(["identify", str(ds), "--report", str(tmp_path / "idrep")])
    assert rc == 0
    assert (tmp_path / "idrep" / "report.md").is_file()
    facts = check_page(browser, tmp_path / "idrep" / "report.html")
    assert len(facts["figures"]) == 2
    assert "parameters identified" in facts["verdict"]
    assert "Cramer-Rao" in facts["verdict"]
    assert facts["footer"].startswith("Made by cdprid identify ")


@needs_chromium
@pytest.mark.slow
def test_diagnose_report_of_the_example(browser, tmp_path):
    """`cdprid diagnose --report` of the example dataset (a finding: its clock offset) renders
    with every figure of report.md; ~20 s of diagnosis, so marked slow (CI runs it)."""
    from cdprid.cli import main
    from cdprid.data import write_sample

    ds = write_sample(tmp_path / "sample")
    rc = main(["diagnose", str(ds), "--quiet", "--report", str(tmp_path / "rep")])
    assert rc == 0
    facts = check_page(browser, tmp_path / "rep" / "report.html")
    pngs = sorted(p.name for p in (tmp_path / "rep").glob("*.png"))
    # every PNG of report.md; its residual_timeline.png is the HTML's timeline (drawn inline)
    assert "residual_timeline.png" in pngs
    assert len(facts["figures"]) == len(pngs)
    assert "finding" in facts["verdict"]


def test_blank_detector_can_fail():
    """The blank check itself: a white image is blank, a drawn one is not."""
    img = np.ones((50, 80, 4))
    assert not not_blank(img)
    img[10:30, 10:60, :3] = 0.2
    assert not_blank(img)


@needs_chromium
def test_checker_catches_a_broken_and_a_blank_figure(browser, tmp_path):
    """check_page fails on a figure that does not decode and on a white figure."""
    from cdprid.report._figures import pyplot
    from cdprid.report._html import img, page, png_bytes

    fig = pyplot().figure(figsize=(4, 3))  # nothing drawn: white
    white = img(png_bytes(fig), "white")
    fig, ax = pyplot().subplots(figsize=(4, 3))
    ax.plot([0, 1], [0, 1])
    drawn = img(png_bytes(fig), "drawn")
    made = {"command": "x", "version": "0"}
    ok = tmp_path / "ok.html"
    ok.write_text(page("t", "v", [drawn], made))
    assert len(check_page(browser, ok)["figures"]) == 1
    for name, body in (("broken", drawn.replace("base64,", "base64,AAAA")), ("blank", white)):
        bad = tmp_path / f"{name}.html"
        bad.write_text(page("t", "v", [drawn, body], made))
        with pytest.raises(AssertionError, match="not decoded|blank"):
            check_page(browser, bad)
