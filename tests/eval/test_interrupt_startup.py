"""Issue 39: Ctrl-C while eval workers (and the forkserver behind them) are starting never
kills one mid-start-up ('Fatal Python error: init_import_site'); the caller gets its
KeyboardInterrupt and nothing else is printed."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="POSIX signals")]

CHILD = textwrap.dedent("""
    import signal, sys, time
    signal.signal(signal.SIGINT, signal.default_int_handler)
    from boids_env.eval.pool import run_isolated

    def work(item):
        time.sleep(0.05)
        return {"item": item}

    if __name__ == "__main__":
        try:
            run_isolated(list(range(40)), work, lambda i, ok, row: None, workers=2)
        except KeyboardInterrupt:
            sys.exit(130)
""")


def _as_in_a_terminal() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("delay", [0.25, 0.4, 0.6, 0.9, 1.4])
def test_ctrl_c_during_worker_start_up_is_a_clean_interrupt(tmp_path, delay):
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path,
                            start_new_session=True, preexec_fn=_as_in_a_terminal,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal does: the whole process group
    _, err = proc.communicate(timeout=120)
    assert "Fatal Python error" not in err, err[-2000:]
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    assert "Traceback" not in err, err[-2000:]
