"""A glue module whose library is missing says which extra to install."""

import importlib
import sys

import pytest


@pytest.mark.parametrize(("module", "library", "extra"), [
    ("benchmarl", "benchmarl", "benchmarl"),
    ("supersuit", "supersuit", "clients,train"),
])
def test_a_missing_library_names_the_extra(monkeypatch, module, library, extra):
    for name in [library, *(m for m in sys.modules if m.startswith(f"{library}."))]:
        monkeypatch.setitem(sys.modules, name, None)  # `import library...` fails
    monkeypatch.delitem(sys.modules, f"boids_env.integrations.{module}", raising=False)
    with pytest.raises(ImportError, match=rf"pip install -e '\.\[{extra}\]'"):
        importlib.import_module(f"boids_env.integrations.{module}")


def test_rllib_without_ray_rllib_names_the_extra(monkeypatch):
    from boids_env.integrations import rllib

    monkeypatch.setitem(sys.modules, "ray.rllib", None)
    with pytest.raises(ImportError, match=r"pip install -e '\.\[rllib\]'"):
        rllib.register("boids_test_missing", robots=3)
