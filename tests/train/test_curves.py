"""`boids curves`: the learning-curves figure of training runs' evaluations."""

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest

pytest.importorskip("matplotlib")

from boids_env.eval import figures
from boids_env.train.cli import main


def write_run(folder, totals, touching):
    folder.mkdir()
    steps = np.arange(1, len(totals) + 1) * 1_000_000
    pd.DataFrame({"timesteps": steps, "V_sep": totals, "total": totals,
                  "touching_fraction": touching, "wall_fraction": 0.0}).to_csv(
        folder / "evaluations.csv", index=False)
    return folder


def test_curves_plot_every_run_as_written(tmp_path, monkeypatch, capsys):
    a = write_run(tmp_path / "a", [3.0, 1.5, 0.5], [0.1, 0.0, 0.0])
    b = write_run(tmp_path / "b", [2.5, 1.0, 0.7], [0.2, 0.05, 0.0])
    seen = {}
    plot = figures.learning_curves

    def spy(runs, path, reference=None, title=""):
        seen.update(runs=runs, reference=reference)
        return plot(runs, path, reference, title)

    monkeypatch.setattr(figures, "learning_curves", spy)
    out = tmp_path / "curves.png"
    assert main(["curves", f"seed 0={a}", str(b / "evaluations.csv"), "--out", str(out),
                 "--reference", "2.427"]) == 0
    assert list(seen["runs"]) == ["seed 0", str(b / "evaluations.csv")]
    np.testing.assert_array_equal(seen["runs"]["seed 0"]["total"], [3.0, 1.5, 0.5])
    assert seen["reference"] == {"total": 2.427}
    image = mpimg.imread(out)
    assert image.shape[1] > 3 * image.shape[0] / 2, "three panels side by side"
    assert out.with_suffix(".svg").is_file()
    svg = out.with_suffix(".svg").read_text()
    assert "Reynolds 2.43" in svg and "seed 0" in svg and "time some robots touch" in svg
    assert f"wrote {out}" in capsys.readouterr().out
    # a rerun replaces the figure (--out names a file here, not an output folder)
    assert main(["curves", str(a), "--out", str(out)]) == 0


def test_curves_refuse_a_folder_without_evaluations_and_a_foreign_csv(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["curves", str(tmp_path / "empty"), "--out", str(tmp_path / "c.png")]) == 2
    assert "no evaluations.csv" in capsys.readouterr().err
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    assert main(["curves", str(tmp_path / "x.csv"), "--out", str(tmp_path / "c.png")]) == 2
    assert "not a boids train evaluations.csv" in capsys.readouterr().err
    assert not (tmp_path / "c.png").exists()
