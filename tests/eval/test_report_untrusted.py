"""The report is built from files anyone can write (a suite TOML, an eval folder's
``suite.json``, ``results.parquet`` and ``errors.jsonl``): their strings are shown, never
obeyed. No tag, link or image comes from a name, no file outside the report's own figures is
inlined, and nothing is read or written outside the folder."""

import base64
import json
import re

import pandas as pd
import pytest

from boids_env.eval.markup import escape
from boids_env.eval.report import build_report
from boids_env.eval.runner import PolicySpec, run_suite
from boids_env.eval.suites import suite_from_dict

SECRET = b"secret-content-of-another-file"


@pytest.fixture
def secret(tmp_path):
    path = tmp_path / "secret.png"
    path.write_bytes(SECRET)
    return path


def _hostile_suite(secret):
    return {"name": "<script>alert(1)</script>", "seeds": 1,
            "defaults": {"robots": 3, "max_cycles": 10},
            "case": [{"name": f"![x]({secret})", "group": "../../escaped"},
                     {"name": f'<img src="{secret}">', "leader_speed": 0.6},
                     {"name": "a | b **bold** `code`\nnext line", "leader_speed": 0.7}]}


def test_hostile_names_are_shown_not_obeyed(tmp_path, secret):
    out = tmp_path / "out"
    run_suite([PolicySpec("reynolds")], suite_from_dict(_hostile_suite(secret)), out,
              backend="inline", progress=False)
    build_report(out)
    html = (out / "report.html").read_text()
    md = (out / "report.md").read_text()
    assert not re.search(r"<script", html, re.I), "a name became a script tag"
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html, "the name is shown as text"
    assert base64.b64encode(SECRET).decode() not in html, "another file was inlined"
    assert all(src.startswith("data:image/") for src in re.findall(r'<img [^>]*src="([^"]*)"',
                                                                   html)), "only our figures"
    assert "<strong>bold</strong>" not in html and "<code>code</code>" not in html
    assert "a \\| b \\*\\*bold\\*\\* \\`code\\` next line" in md, "one cell, escaped"
    # the group name became a file name inside figures/, not a path out of the folder
    assert not (tmp_path / "escaped.png").exists() and not list(tmp_path.glob("*escaped*"))
    assert any("escaped" in p.name for p in (out / "figures").iterdir())


def test_an_edited_suite_json_inlines_no_other_file(tmp_path, secret):
    out = tmp_path / "out"
    run_suite([PolicySpec("reynolds")], suite_from_dict(
        {"name": "ok", "seeds": 1, "defaults": {"robots": 3, "max_cycles": 10},
         "case": [{"name": "a"}]}), out, backend="inline", progress=False)
    suite = json.loads((out / "suite.json").read_text())
    suite["name"] = f'<img src="{secret}"> ![y]({secret})'
    suite["policies"][0]["label"] = f"![z](figures/../../{secret.name})"
    (out / "suite.json").write_text(json.dumps(suite))
    table = pd.read_parquet(out / "results.parquet")
    table["trajectory"] = "../../secret.png"  # a trajectory path leading out of the folder
    table.to_parquet(out / "results.parquet", index=False)
    (out / "figures").mkdir(exist_ok=True)
    build_report(out)
    html = (out / "report.html").read_text()
    assert base64.b64encode(SECRET).decode() not in html
    assert "'../../secret.png' is not a file inside trajectories/" in html
    for tag in re.findall(r"<img [^>]*>", html):
        assert 'src="data:image/' in tag, f"an image that is not our figure: {tag}"


def test_a_figure_linked_out_of_the_folder_is_not_inlined(tmp_path, secret, monkeypatch):
    from boids_env.eval import html as html_module

    base = tmp_path / "report"
    (base / "figures").mkdir(parents=True)
    (base / "figures" / "safety.png").symlink_to(secret)
    page = html_module.write_html("![s](figures/safety.png)\n", base / "report.html", "t", base,
                                  ["figures/safety.png"])
    assert base64.b64encode(SECRET).decode() not in page.read_text()


@pytest.mark.parametrize("text, shown", [
    ("<b>x</b>", "&lt;b&gt;x&lt;/b&gt;"),
    ("[a](b)", "\\[a\\]\\(b\\)"),
    ("x|y", "x\\|y"),
    ("two\nlines", "two lines"),
    ("A & B", "A &amp; B"),
    ("plain name 0.5", "plain name 0.5"),
])
def test_escape(text, shown):
    assert escape(text) == shown


@pytest.mark.parametrize("key, value, match", [
    ("followers_analysed", 2**40, r"followers_analysed must be in \[1, 10000\]"),
    ("followers_analysed", "6", "followers_analysed must be"),
    ("policies", [{"spec": "x"}], "policies must be tables with a label"),
    ("cases", None, "cases must be a list"),
])
def test_an_edited_suite_json_is_refused_by_key_before_it_sizes_anything(tmp_path, key, value,
                                                                         match):
    out = tmp_path / "out"
    run_suite([PolicySpec("reynolds")], suite_from_dict(
        {"name": "ok", "seeds": 1, "defaults": {"robots": 3, "max_cycles": 10},
         "per_follower": ["g"], "case": [{"name": "a", "group": "g"}]}), out,
        backend="inline", progress=False)
    suite = json.loads((out / "suite.json").read_text())
    suite[key] = value
    (out / "suite.json").write_text(json.dumps(suite))
    with pytest.raises(ValueError, match=match):
        build_report(out)
