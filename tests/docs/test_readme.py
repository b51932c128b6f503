"""The README's links and its command list are true: every relative link resolves to a file
of the repository (the site is built from docs/, so a page linked there is a page of the
site), and the commands it names are the ones ``boids --help`` lists."""

import re
from pathlib import Path

from boids_env.train.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()
LINK = re.compile(r"\]\(([^)\s]+)\)")


def test_every_relative_link_of_the_readme_resolves_in_the_repository():
    targets = [t for t in LINK.findall(README) if not re.match(r"[a-z]+:", t)]
    assert targets, "the README links nothing"
    missing = [t for t in targets
               if t.split("#")[0] and not (ROOT / t.split("#")[0]).exists()]
    assert not missing, f"README links to files that do not exist: {missing}"


def test_the_readme_names_every_command_boids_help_lists():
    parser = build_parser()
    (sub,) = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
    listed = re.search(r"`boids --help` lists the commands \(([^)]*)\)", README)
    assert listed, "the README's command list is gone"
    named = set(re.findall(r"`([a-z0-9]+)`", listed.group(1)))
    assert named == set(sub.choices), (named ^ set(sub.choices))
