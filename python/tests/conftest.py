"""What the Python package's tests share: the repository's root (the working directory of
every test, where `scenes/` is) and the command line's binary, to compare against."""

import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def tessera_binary() -> Path:
    """The `tessera` command the package is compared with: $TESSERA_BIN, else the release
    build in the repository's target directory, else one on PATH."""
    given = os.environ.get("TESSERA_BIN")
    if given:
        return Path(given)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    built = target / "release" / "tessera"
    if built.exists():
        return built
    found = shutil.which("tessera")
    if found:
        return Path(found)
    pytest.fail("no tessera binary: build it (cargo build --release) or set TESSERA_BIN")


@pytest.fixture(autouse=True)
def at_root(monkeypatch):
    monkeypatch.chdir(ROOT)


@pytest.fixture(scope="session")
def cli():
    """Runs the command line; returns its completed process (output as text)."""
    binary = tessera_binary()

    def run(*args, check=True):
        done = subprocess.run(
            [str(binary), *map(str, args)],
            cwd=ROOT,
            capture_output=True,
            text=True,
        )
        if check and done.returncode != 0:
            raise AssertionError(f"tessera {' '.join(map(str, args))}: {done.stderr}")
        return done

    return run


def read_ppm(path: Path):
    """The pixels of a plain (P3) PPM file, as tessera writes it: width, height, values."""
    words = path.read_text().split()
    assert words[0] == "P3" and words[3] == "255", words[:4]
    width, height = int(words[1]), int(words[2])
    values = bytes(int(w) for w in words[4:])
    assert len(values) == width * height * 3
    return width, height, values


def as_at_a_terminal():
    """Ctrl-C's default action in the child, as a shell with job control gives a program it
    starts: Python then raises KeyboardInterrupt for it. A shell without job control (a
    script's `cmd &`, CI run in the background) starts its children with Ctrl-C ignored,
    and Python, and tessera with it, then leave it ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
