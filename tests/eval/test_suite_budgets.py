"""Issue 39: a suite file is read within budgets (byte size, nesting, case count) and its
names are checked and escaped where they enter, before any case is validated or run."""

import os

import pytest

from boids_env.eval.suites import load_suite


def _suite(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("body", [
    "[[factor]]\nname = \"robots\"\nlevels = [" + ",".join(["13"] * 20_000) + "]\n",
    "[[case]]\n" * 20_000,
])
def test_twenty_thousand_cases_are_refused_before_any_is_validated(tmp_path, body):
    with pytest.raises(ValueError, match=r"20,000 cases, more than the 1,000 allowed"):
        load_suite(_suite(tmp_path, "seeds = 1\n" + body))


def test_repeated_case_names_are_quoted_briefly(tmp_path):
    body = "[[factor]]\nname = \"robots\"\nlevels = [" + ",".join(["13"] * 900) + "]\n"
    with pytest.raises(ValueError, match="case names must be unique; 1 repeated") as info:
        load_suite(_suite(tmp_path, "seeds = 1\n" + body))
    assert len(str(info.value)) < 300, len(str(info.value))


def test_deep_nesting_is_a_value_error(tmp_path):
    with pytest.raises(ValueError, match="nested more than 32 levels"):
        load_suite(_suite(tmp_path, "seeds = " + "[" * 3000 + "]" * 3000 + "\n"))


def test_a_long_case_name_is_refused_before_the_run(tmp_path):
    path = _suite(tmp_path, f'seeds = 1\n[[case]]\nname = "{"x" * 300}"\nmax_cycles = 5\n')
    with pytest.raises(ValueError, match="name must be at most 100 characters, got 300"):
        load_suite(path)


def test_escape_sequences_in_names_are_escaped(tmp_path):
    path = _suite(tmp_path, 'name = "\\u001b[31mevil"\nseeds = 1\n[[case]]\n'
                            'name = "c\\u001b[2Jx"\ngroup = "g\\u0007"\nmax_cycles = 5\n')
    suite = load_suite(path)
    assert suite.name == "\\x1b[31mevil"
    case = suite.cases[0]
    assert (case.name, case.group, case.level) == ("c\\x1b[2Jx", "g\\x07", "c\\x1b[2Jx")


def test_a_fifo_or_a_device_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "s.toml"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match=r"not a regular file \(a FIFO"):
        load_suite(fifo)
    with pytest.raises(ValueError, match=r"not a regular file \(a character device"):
        load_suite("/dev/zero")
