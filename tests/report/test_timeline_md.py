"""report.md's residual timeline: the episodes shaded and labelled (issue 38 item 6), on a
DiagnosisResult built here (the report's inputs, not a diagnosis run)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import to_rgb  # noqa: E402

from cdprid.diagnosis import DiagnosisResult, Finding  # noqa: E402
from cdprid.report import save_report  # noqa: E402
from cdprid.report._html import EPISODE_COLOURS, episode_bands  # noqa: E402

EPISODES = [{"start_s": 3.0, "end_s": 5.0, "kind": "external_wrench", "size_N": 9.0,
             "size_Nm": 0.4, "p_value": 1e-9},
            {"start_s": 11.0, "end_s": 12.5, "kind": "energy", "energy_J": 1.5,
             "p_value": 1e-6}]


def _result(episodes):
    rng = np.random.default_rng(3)
    t = np.arange(0, 20, 0.02)
    ext = 0.2 * rng.standard_normal((len(t), 6))
    base = ext.copy()
    base[:, 0] += 0.8 * np.sin(2 * np.pi * 0.5 * t)
    par = {"m": {"value": 6.3, "std": 0.003, "rel_std_percent": 0.05}}
    f = Finding("time_delay", {"delay_s": -0.005}, {"delay_s": [-0.0052, -0.0048]}, [],
                0.97, 0.72, 1e-12, 2050.0, 1e-5)
    res = DiagnosisResult(
        base_parameters=par, base_residual_rms=[0.5] * 6, base_heldout_rms=0.36,
        findings=[f], extended_parameters=par, extended_heldout_rms=0.27, ranking=[],
        info={"heldout": "blocked 5-fold CV", "train_until": None,
              "information_criterion": {"kind": "BIC", "base": 1.0, "extended": 0.5}},
        arrays={"t": t, "residual_base": base, "residual_extended": ext,
                "use": np.ones(len(t), bool), "train": np.ones(len(t), bool),
                "velocity": rng.standard_normal((len(t), 3)),
                "acceleration": rng.standard_normal((len(t), 3)),
                "tension": 50 + rng.standard_normal((len(t), 4)),
                "position": rng.standard_normal((len(t), 3))})
    object.__setattr__(res, "episodes", episodes)
    return res


def test_episode_bands_shade_and_label_each_episode():
    fig, ax = plt.subplots()
    ax.set_xlim(0, 20)
    drawn = episode_bands(ax, EPISODES)
    assert len(drawn) == 2
    for (band, text), e in zip(drawn, EPISODES, strict=True):
        x = (np.array([band.get_x(), band.get_x() + band.get_width()])
             if hasattr(band, "get_width") else np.asarray(band.get_xy())[:, 0])
        assert np.isclose(x.min(), e["start_s"]) and np.isclose(x.max(), e["end_s"])
        assert text.get_text().endswith(e["kind"])
        assert e["start_s"] < text.get_position()[0] < e["end_s"]
    assert drawn[0][0].get_facecolor() != drawn[1][0].get_facecolor()  # one colour per kind
    labels = ax.get_legend_handles_labels()[1]
    assert labels == ["episode: energy", "episode: external_wrench"]
    plt.close(fig)


def test_report_md_has_the_timeline_with_the_episodes(tmp_path):
    with_eps, without = tmp_path / "a", tmp_path / "b"
    save_report(_result(EPISODES), with_eps, "data")
    save_report(_result([]), without, "data")
    md = (with_eps / "report.md").read_text()
    assert "![residual_timeline](residual_timeline.png)" in md
    a, b = with_eps / "residual_timeline.png", without / "residual_timeline.png"
    assert a.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the bands: columns holding the blend of an episode colour over white (alpha 0.25)
    widths = []
    for png in (a, b):
        img = mpimg.imread(png)[..., :3]
        top = img[int(0.1 * img.shape[0]):int(0.25 * img.shape[0])]  # above the data
        band = 0.75 + 0.25 * np.asarray(to_rgb(EPISODE_COLOURS[1]))  # external_wrench
        hit = np.all(np.abs(top - band) < 0.03, axis=2).any(0)
        widths.append(hit.sum() / img.shape[1])
    # 2 of the 20 s: about 10 % of the axes, which are ~85 % of the image wide (less the
    # label's box)
    assert 0.04 < widths[0] < 0.1 and widths[1] == 0.0, widths
