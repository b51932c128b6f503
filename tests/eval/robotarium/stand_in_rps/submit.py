"""Run a Robotarium script as the testbed would: ``python submit.py SCRIPT REPORT``.

Refuses (exit 3) a script that imports a module the Robotarium does not offer (its imports
read with ``ast``, before anything runs), then runs it with this folder's ``rps`` first on the
path and the report of its ``Robotarium`` written to REPORT (``rps/robotarium.py``). Exit 0:
it ran and finished (``debug()`` or ``call_at_scripts_end()``) with no rejection; 1: rejected
by a rule; 2: it raised or never finished.
"""

import ast
import json
import os
import runpy
import sys
import traceback

ALLOWED = {"rps", "numpy", "math", "scipy", "cvxopt", "matplotlib", "torch", "shapely",
           "networkx", "time"}
"""Top-level modules a submission may import (the Robotarium's libraries.txt, the part a
flock needs, plus the standard library's math and time)."""


def imports(source):
    """Top-level names of every module ``source`` imports (relative imports as '.')."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.add("." if node.level else (node.module or "").split(".")[0])
        elif isinstance(node, ast.Call) and getattr(node.func, "id", "") == "__import__":
            names.add("__import__")
    return names


def main(script, report_path):
    with open(script) as f:
        source = f.read()
    bad = sorted(imports(source) - ALLOWED)
    report = {"disallowed_imports": bad}
    if bad:
        with open(report_path, "w") as f:
            json.dump({**report, "rejected": True}, f)
        print(f"rejected: imports not allowed on the Robotarium: {bad}")
        return 3
    os.environ["STAND_IN_RPS_REPORT"] = report_path
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    if os.path.exists(report_path):
        os.remove(report_path)
    try:
        runpy.run_path(script, run_name="__main__")
    except Exception:
        traceback.print_exc()
        return 2
    if not os.path.exists(report_path):
        print("the script never called debug() / call_at_scripts_end()")
        return 2
    with open(report_path) as f:
        ran = json.load(f)
    ran.update(report)
    with open(report_path, "w") as f:
        json.dump(ran, f)
    return 1 if ran["rejected"] else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
