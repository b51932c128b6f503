"""Issue 39, "small files, huge costs": a map or shapes file of a few hundred bytes that
would have taken minutes or gigabytes is refused, before anything large is allocated, with a
message naming the field and the limit. Each case also runs in a subprocess whose address
space is capped (RLIMIT_AS), so a regression fails with a MemoryError instead of eating the
machine."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from PIL import Image

from boids_env.world import maps
from boids_env.world.scenes import load_scene


def _laughs(levels: int, width: int = 9) -> str:
    """YAML anchors each naming ``width`` copies of the previous one ('billion laughs')."""
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for k in range(1, levels + 1):
        lines.append(f"l{k}: &l{k} [" + ", ".join([f"*l{k - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


def _free_map(folder, name="m", size=(10, 10), **fields):
    Image.fromarray(np.full(size, 254, dtype=np.uint8)).save(folder / f"{name}.pgm")
    body = {"image": f"{name}.pgm", "resolution": 0.1, "origin": "[-0.5, -0.5, 0]", **fields}
    path = folder / f"{name}.yaml"
    path.write_text("".join(f"{k}: {v}\n" for k, v in body.items()))
    return path


def test_billion_laughs_in_a_map_yaml_is_refused_by_its_aliases(tmp_path):
    path = _free_map(tmp_path)
    path.write_text(path.read_text().replace("resolution: 0.1\n", "") + _laughs(8)
                    + "resolution: *l8\n")
    assert path.stat().st_size < 600
    with pytest.raises(ValueError, match=r"map .*m\.yaml: more than 64 YAML aliases"):
        maps.load_map(path)


def test_an_expanded_alias_is_never_quoted_in_the_message(tmp_path):
    # 6 levels (48 aliases, under the alias bound): 9**6 "lol"s used to be printed in full
    path = _free_map(tmp_path)
    path.write_text(path.read_text().replace("resolution: 0.1\n", "") + _laughs(5)
                    + "resolution: *l5\n")
    with pytest.raises(ValueError) as info:
        maps.load_map(path)
    assert "expands to more than 100,000 values" in str(info.value)
    assert len(str(info.value)) < 300, len(str(info.value))
    path = _free_map(tmp_path)
    path.write_text(path.read_text().replace("resolution: 0.1\n", "") + _laughs(2)
                    + "resolution: *l2\n")  # 729 values: read, then quoted in a bounded way
    with pytest.raises(ValueError, match="resolution must be a number") as info:
        maps.load_map(path)
    assert len(str(info.value)) < 300, len(str(info.value))


@pytest.mark.parametrize("text, match", [
    ("a: " + "[" * 5000 + "]" * 5000, "nested more than 32 levels"),
    ("a: &a [*a]\nimage: m.pgm", "contains it"),
])
def test_deep_or_recursive_yaml_is_a_value_error(tmp_path, text, match):
    path = tmp_path / "m.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        maps.load_map(path)


def test_a_tiny_image_with_huge_cells_is_refused_by_its_extent(tmp_path):
    path = _free_map(tmp_path, resolution=100, origin="[-500, -500, 0]")
    with pytest.raises(ValueError, match=r"resolution 100 m span 1000 m × 1000 m; a scene "
                                         r"may span at most 500 m"):
        maps.load_map(path)


def test_a_checkerboard_map_is_refused_by_its_boundary_before_tracing(tmp_path):
    y, x = np.mgrid[0:1024, 0:1024]
    Image.fromarray(np.where((x + y) % 2, 0, 254).astype(np.uint8)).save(tmp_path / "c.png")
    path = tmp_path / "c.yaml"
    path.write_text("image: c.png\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(ValueError, match=r"2,097,152 boundary cell edges, more than the "
                                         r"400,000 allowed"):
        maps.load_map(path)


@pytest.mark.parametrize("fmt", ["GIF", "BMP", "TIFF"])
def test_only_png_and_pgm_images_are_read(tmp_path, fmt):
    Image.fromarray(np.full((4, 4), 254, dtype=np.uint8)).save(tmp_path / "m.img", format=fmt)
    path = tmp_path / "m.yaml"
    path.write_text("image: m.img\nresolution: 0.5\norigin: [-1, -1, 0]\n")
    with pytest.raises(ValueError, match="is not a PNG or PGM file"):
        maps.load_map(path)


def test_an_eps_named_pgm_never_reaches_pillow(tmp_path, monkeypatch):
    (tmp_path / "m.pgm").write_bytes(b"%!PS-Adobe-3.0 EPSF-3.0\n%%BoundingBox: 0 0 4 4\n")
    path = tmp_path / "m.yaml"
    path.write_text("image: m.pgm\nresolution: 0.5\norigin: [-1, -1, 0]\n")
    import PIL.Image

    def no_open(*args, **kwargs):
        raise AssertionError("Pillow was asked to open a file that is not a PNG or PGM")

    monkeypatch.setattr(PIL.Image, "open", no_open)
    with pytest.raises(ValueError, match="is not a PNG or PGM file"):
        maps.load_map(path)


@pytest.mark.parametrize("suffix", [".yaml", ".toml"])
def test_special_files_are_refused_without_reading(tmp_path, suffix):
    zero = tmp_path / f"zero{suffix}"
    zero.symlink_to("/dev/zero")
    with pytest.raises(ValueError, match="not a regular file \\(a character device\\)"):
        load_scene(str(zero))
    fifo = tmp_path / f"fifo{suffix}"
    os.mkfifo(fifo)  # nobody writes to it: reading it would block for ever
    with pytest.raises(ValueError, match="not a regular file \\(a FIFO"):
        load_scene(str(fifo))


def test_a_shapes_file_with_a_huge_box_is_refused_by_its_box(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("box = [-1000.0, -1000.0, 1000.0, 1000.0]\n[[circle]]\ncenter = [1.0, 1.0]\n"
                    "radius = 0.1\n")
    with pytest.raises(ValueError, match=r"box spans 2000 m × 2000 m; a scene may span at most"):
        load_scene(str(path))
    path.write_text("[[circle]]\ncenter = [-900.0, 0.0]\nradius = 0.1\n"
                    "[[circle]]\ncenter = [900.0, 0.0]\nradius = 0.1\n")
    with pytest.raises(ValueError, match=r"spans 1800.2 m × 0.2 m; a scene with shapes may"):
        load_scene(str(path))


def test_deeply_nested_shapes_files_are_value_errors(tmp_path):
    toml = tmp_path / "s.toml"
    toml.write_text("box = " + "[" * 3000 + "]" * 3000 + "\n")
    with pytest.raises(ValueError, match="nested more than 32 levels"):
        load_scene(str(toml))
    js = tmp_path / "s.json"
    js.write_text('{"box": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(ValueError, match="nested more than 32 levels"):
        load_scene(str(js))


def test_a_shapes_name_with_escape_sequences_is_escaped(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('name = "\\u001b[2J\\u001b]0;pwned\\u0007room"\n'
                    'description = "a\\u001b[31m red room"\nbox = [-2.0, -2.0, 2.0, 2.0]\n')
    scene = load_scene(str(path))
    assert scene.name == "\\x1b[2J\\x1b]0;pwned\\x07room"
    assert "\x1b" not in scene.description and "\\x1b[31m" in scene.description


CAPPED = textwrap.dedent("""
    import resource, sys
    resource.setrlimit(resource.RLIMIT_AS, (1_500_000_000, 1_500_000_000))
    from boids_env.world.scenes import load_scene
    try:
        load_scene(sys.argv[1])
    except ValueError as exc:
        print("refused:", exc)
""")


@pytest.mark.slow
def test_small_files_are_refused_within_a_memory_cap(tmp_path):
    """Each small file of the issue, loaded in a process of 1.5 GB address space (the
    interpreter, numpy and Pillow take about 1 GB of it): refused, no MemoryError."""
    laughs = _free_map(tmp_path, "laughs")
    laughs.write_text(laughs.read_text().replace("resolution: 0.1\n", "") + _laughs(8)
                      + "resolution: *l8\n")
    huge = _free_map(tmp_path, "huge", resolution=100)
    y, x = np.mgrid[0:4096, 0:4096]
    Image.fromarray(np.where((x + y) % 2, 0, 254).astype(np.uint8)).save(tmp_path / "c.png")
    (tmp_path / "c.yaml").write_text("image: c.png\nresolution: 0.05\norigin: [0, 0, 0]\n")
    (tmp_path / "box.toml").write_text("box = [-1000.0, -1000.0, 1000.0, 1000.0]\n")
    for path in (laughs, huge, tmp_path / "c.yaml", tmp_path / "box.toml"):
        done = subprocess.run([sys.executable, "-c", CAPPED, str(path)], capture_output=True,
                              text=True, timeout=120)
        assert done.returncode == 0 and done.stdout.startswith("refused:"), \
            (path.name, done.stdout[-300:], done.stderr[-600:])
