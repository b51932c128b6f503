import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import pytest


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_pytests_tmp(tmp_path_factory: pytest.TempPathFactory) -> None:
    """SB3's ``learn()`` without a log folder makes an empty ``SB3-<date>`` folder in the
    system's temp dir on every call; pointed at pytest's own temp dir, the suite leaves none
    behind."""
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3"))
