"""The figures a user sees read on their own: a title, every drawn axis labelled, distinct series styles.

Each figure is drawn from a tiny dataset or synthetic data; ``save_figure`` is intercepted so the test looks
at the matplotlib figure itself."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import matplotlib.figure
import numpy as np
import pytest

from hysbench.benchmarks.compensation import report as compensation_report
from hysbench.benchmarks.matrix.report import error_figure, loops_figure
from hysbench.benchmarks.plots import axis_label, figure_legend, pyplot, series_style, unreadable
from hysbench.benchmarks.reports.identification import convergence_figure
from hysbench.benchmarks.reports.posterior import predictive_figure
from hysbench.data.dataset import load_dataset
from hysbench.identification import identify

from tiny_dataset import tiny_records, write_tiny_dataset


@pytest.fixture
def drawn(monkeypatch):
    """The figures saved while the test runs (nothing is rendered)."""
    figures = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda fig, *a, **k: figures.append(fig))
    return figures


def _cell(fit) -> dict:
    d = fit.to_dict()
    return {"model": d["model"], "method": d["method"], "fit": d,
            "records": [dataclasses.asdict(r) for r in fit.records]}


@pytest.mark.parametrize("periodic", [True, False])
def test_matrix_figures_are_labelled(tmp_path, drawn, periodic):
    records = tiny_records() if periodic else {f"drive{i}.npz": v for i, v in enumerate(tiny_records().values())}
    folder = write_tiny_dataset(tmp_path / "tiny", records=records,
                                roles=None if periodic else {"drive2.npz": "validation"})
    ds = load_dataset(folder)
    fit = identify("classical-pi", ds, method="varpro")
    best = [(_cell(fit), {})]
    loops_figure(ds, best, tmp_path)
    error_figure(ds, best, tmp_path)
    loops, errors = drawn
    assert unreadable(loops) == [] and unreadable(errors) == []
    assert errors.axes[0].get_yscale() == "log"
    assert any("validation" in ax.get_title() for ax in errors.axes)
    assert not loops.axes[0].get_legend()  # the legend is the figure's, below the panels
    xlabel = loops._supxlabel.get_text()
    assert xlabel == "input" if periodic else xlabel == "time (s)"


def test_convergence_and_predictive_figures_are_labelled(tmp_path, drawn):
    ds = load_dataset(write_tiny_dataset(tmp_path / "tiny"))
    convergence_figure([("classical-pi", [identify("classical-pi", ds, method="varpro")])], tmp_path / "c.png")
    t = np.linspace(0, 1, 50)
    pred = [{"frequency_hz": 1.0, "file": "f1Hz.npz", "_t": t, "_y": t, "_median": t, "_obs": (t - 1, t + 1),
             "_model": (t - 0.5, t + 0.5), "fraction_inside_observation_band": 0.9}]
    predictive_figure(pred, tmp_path / "p.png", unit="um")
    assert [unreadable(fig) for fig in drawn] == [[], []]
    assert drawn[1].axes[0].get_ylabel() == "output (µm)"


def test_compensation_figure_is_labelled(tmp_path, drawn):
    n = 30_000
    ref = SimpleNamespace(y=np.sin(np.arange(n) * 1e-3), scored=slice(1000, n))
    runs = {"random": {c: SimpleNamespace(reference=ref, y=ref.y + 0.1 * i, u=ref.y) for i, c in
                       enumerate(("linear", "mrpim", "pi"))}}
    compensation_report.figure(runs, "random", ["linear", "mrpim", "pi"], tmp_path / "c.png", pyplot())
    (fig,) = drawn
    assert unreadable(fig) == []
    t = fig.axes[0].lines[0].get_xdata()
    assert t[-1] - t[0] < compensation_report.PLOT_SECONDS  # a long reference is shown by its end
    assert "last" in fig.axes[2].get_xlabel()


def test_unreadable_names_what_is_missing():
    fig, axes = pyplot().subplots(1, 2)
    for ax in axes:
        ax.plot([0, 1], [0, 1])
    axes[0].set_xlabel("x (s)")
    problems = unreadable(fig)
    assert "the figure has no title" in problems and len(problems) == 4  # no title, one x and two y labels
    fig.suptitle("t")
    fig.supylabel("y (mm)")
    axes[1].set_xlabel("x (s)")
    assert unreadable(fig) == []
    pyplot().close(fig)


def test_unreadable_names_a_title_a_legend_covers():
    fig, axes = pyplot().subplots(1, 3, figsize=(9, 3), layout="constrained")
    for i, ax in enumerate(axes):
        ax.plot([0, 1], [0, i], label=f"a model with a long name {i}")
    fig.supxlabel("x (s)")
    fig.supylabel("y (mm)")
    figure_legend(fig, axes[0])
    fig.suptitle("a title long enough to run from the left edge of the panels under the legend beside them, "
                 "as one line")
    assert any("runs under a legend" in p for p in unreadable(fig))
    fig.suptitle("a short title")
    assert unreadable(fig) == []
    pyplot().close(fig)


def test_series_styles_and_units():
    styles = [series_style(i) for i in range(14)]
    assert len({tuple(sorted(s.items())) for s in styles}) == 14
    assert styles[0]["color"] == styles[10]["color"] and styles[0] != styles[10]  # a repeated colour, restyled
    assert axis_label("output", "uC/cm2") == "output (µC/cm²)" and axis_label("output", "") == "output"


def test_amplitude_figure_is_labelled(tmp_path, drawn, monkeypatch):
    from hysbench.benchmarks.reports import amplitude

    rows = [{"model": f"m{i}", "method": "varpro", "kind": "grey-box", "n_params": 3,
             "e_rms": {a: 10.0 ** (i - 6) * (1 + a) for a in amplitude.AMPLITUDES_KV}} for i in range(12)]
    monkeypatch.setattr(amplitude, "study", lambda results_dir: rows)
    amplitude.write(tmp_path)
    (fig,) = drawn
    assert unreadable(fig) == [] and len({line.get_marker() for line in fig.axes[0].lines}) > 1


def test_diagnosis_panels_of_records_that_share_a_frequency_name_their_files():
    from hysbench.benchmarks.diagnosis.figures import _label
    from hysbench.data.dataset import Record

    t = np.arange(200) * 0.01
    recs = [Record(file=f, t=t, u=np.sin(2 * np.pi * t), y=np.cos(2 * np.pi * t), role=role, frequency_hz=hz)
            for f, role, hz in (("a.csv", "identification", 1.0), ("b.csv", "validation", 1.0),
                                ("c.csv", "identification", 2.0))]
    diag = SimpleNamespace(before=[SimpleNamespace(record=r) for r in recs])
    assert [_label(r, diag) for r in recs] == ["1 Hz, a.csv (id)", "1 Hz, b.csv (val)", "2 Hz (id)"]


def test_predictive_panels_of_records_that_share_a_frequency_name_their_files(tmp_path, drawn):
    t = np.linspace(0, 1, 50)
    pred = [{"frequency_hz": 1.0, "file": f, "_t": t, "_y": t, "_median": t, "_obs": (t - 1, t + 1),
             "_model": (t - 0.5, t + 0.5), "fraction_inside_observation_band": 0.9} for f in ("a.csv", "b.csv")]
    predictive_figure(pred + [dict(pred[0], frequency_hz=2.0, file="c.csv")], tmp_path / "p.png", unit="um")
    titles = [ax.get_title() for ax in drawn[0].axes[::2]]
    assert [t.split(":")[0] for t in titles] == ["1 Hz, a.csv", "1 Hz, b.csv", "2 Hz"]
