"""The committed vectors are what their generators print today: a change
to a generator (or a hand edit of a .txt) without regenerating fails here,
so the C tests and danprobe's never check against a stale file."""

import shutil
import subprocess
import sys

from conftest import VECTORS


def run(gen, cwd, out=None):
    r = subprocess.run(
        [sys.executable, gen], cwd=cwd, capture_output=True, text=True, timeout=120, check=True
    )
    if out is not None:
        (cwd / out).write_text(r.stdout)


def test_vectors_match_generators(tmp_path):
    work = tmp_path / "vectors"
    shutil.copytree(VECTORS, work)
    for f in work.glob("*.txt"):
        f.unlink()
    run("gen_vectors.py", work)
    run("gen_gateway.py", work, "gateway.txt")
    run("gen_dronecan.py", work, "dronecan.txt")
    made = sorted(f.name for f in work.glob("*.txt"))
    assert made == sorted(f.name for f in VECTORS.glob("*.txt"))
    for name in made:
        assert (work / name).read_text() == (VECTORS / name).read_text(), (
            "tests/vectors/%s is stale: regenerate it (see its header)" % name
        )
