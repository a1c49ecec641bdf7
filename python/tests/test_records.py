"""tessera.reproduce, tessera.bench and tessera.results against what the command line says
of the same files and databases."""

import json
import warnings

import pytest

import tessera
from conftest import ROOT, as_at_a_terminal


def test_reproduce_says_identical_for_its_own_image_and_the_cli_agrees(cli, tmp_path):
    image = tessera.render("scenes/img-2.16-rect-light.toml", width=40, spp=4)
    image.save(tmp_path / "light.png")
    verdict = tessera.reproduce(tmp_path / "light.png", threads=1, simd="portable")
    assert verdict["verdict"] == "identical", verdict
    assert verdict["sums"] == image.sums and verdict["details"] == []
    assert "40x" in verdict["work"]
    said = cli("reproduce", tmp_path / "light.png", "-q").stdout
    assert said.startswith("identical: "), said


def test_reproduce_finds_a_texture_and_says_differs_for_another_image(cli, tmp_path):
    earth = tessera.render("scenes/img-2.15-earth-sphere.toml", width=40, spp=2)
    earth.save(tmp_path / "earth.png")
    # Next to the image, not in scenes/: the recipe's texture is looked for there too.
    assert tessera.reproduce(tmp_path / "earth.png")["verdict"] == "identical"
    # The same file with another image's pixels (same size) in it: its recipe makes another.
    a = tessera.render("scenes/cover.toml", width=40, spp=1, seed=1)
    b = tessera.render("scenes/cover.toml", width=40, spp=1, seed=2)
    recipe_a = a.png()
    b.save(tmp_path / "b.png")
    # Swap b's recipe for a's by writing a's PNG over with b's pixels: the CLI's own check.
    (tmp_path / "a.png").write_bytes(recipe_a)
    mixed = _png_with_pixels_of(tmp_path / "a.png", tmp_path / "b.png")
    (tmp_path / "mixed.png").write_bytes(mixed)
    verdict = tessera.reproduce(tmp_path / "mixed.png")
    assert verdict["verdict"] == "differs", verdict
    assert any(line.startswith("pixels: ") for line in verdict["details"]), verdict
    cli_said = cli("reproduce", tmp_path / "mixed.png", "-q", check=False)
    assert cli_said.returncode == 1 and cli_said.stdout.startswith("differs: ")


def _png_with_pixels_of(recipe_from, pixels_from):
    """A's chunks with B's image data: both are tessera's PNGs of one size."""
    def chunks(data):
        at, out = 8, []
        while at < len(data):
            length = int.from_bytes(data[at:at + 4], "big")
            out.append((data[at + 4:at + 8], data[at:at + 12 + length]))
            at += 12 + length
        return out
    a = chunks(recipe_from.read_bytes())
    b_data = [raw for kind, raw in chunks(pixels_from.read_bytes()) if kind == b"IDAT"]
    out = bytearray(b"\x89PNG\r\n\x1a\n")
    placed = False
    for kind, raw in a:
        if kind == b"IDAT":
            if not placed:
                out += b"".join(b_data)
                placed = True
            continue
        out += raw
    return bytes(out)


def _png_with_recipe(png, recipe):
    """`png` (tessera's) with its recipe chunk replaced by `recipe`, uncompressed."""
    import zlib
    at, out = 8, bytearray(png[:8])
    while at < len(png):
        length = int.from_bytes(png[at:at + 4], "big")
        kind = png[at + 4:at + 8]
        if kind == b"IEND":
            data = b"tessera-recipe\0\0\0\0\0" + json.dumps(recipe).encode()
            crc = zlib.crc32(b"iTXt" + data)
            out += len(data).to_bytes(4, "big") + b"iTXt" + data + crc.to_bytes(4, "big")
        if kind != b"iTXt":
            out += png[at:at + 12 + length]
        at += 12 + length
    return bytes(out)


def test_reproduce_judges_the_work_by_its_paths_traced_and_refuses_more_unless_asked(tmp_path):
    # 4,000 nested glass shells: a ray meets each, so a path costs tens of the cover's.
    scene = ("[image]\nwidth = 320\nheight = 180\nsamples_per_pixel = 20000\nmax_depth = 50\n"
             "[render]\nshading = \"path\"\n"
             "[materials.glass]\ntype = \"dielectric\"\nir = 1.5\n")
    scene += "".join(
        f"[[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = {0.3 + 0.2 * i / 4000:.6f}\n"
        f"material = \"glass\"\n" for i in range(4000))
    one = tessera.render(scene, spp=1, width=320)
    one.save(tmp_path / "one.png")
    verdict = tessera.reproduce(tmp_path / "one.png")
    assert verdict["verdict"] == "identical", verdict
    assert "times the cover's" in verdict["work"], verdict["work"]
    recipe = one.recipe
    recipe["overrides"] = {"width": 320}
    recipe["image"]["samples_per_pixel"] = 20000
    (tmp_path / "shells.png").write_bytes(_png_with_recipe(one.png(), recipe))
    with pytest.raises(tessera.TesseraError, match="pass any_cost=True to render it anyway"):
        tessera.reproduce(tmp_path / "shells.png")


def test_reproduce_stops_a_render_past_its_time_budget(tmp_path, monkeypatch):
    scene = ("[image]\nwidth = 240\nheight = 135\nsamples_per_pixel = 16\nmax_depth = 50\n"
             "[render]\nshading = \"path\"\n[materials.glass]\ntype = \"dielectric\"\nir = 1.5\n")
    scene += "".join(
        f"[[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = {0.3 + 0.2 * i / 4000:.6f}\n"
        f"material = \"glass\"\n" for i in range(4000))
    tessera.render(scene).save(tmp_path / "shells.png")
    monkeypatch.setenv("TESSERA_REPRODUCE_SECONDS", "0.01")
    with pytest.raises(tessera.TesseraError, match="stopped after .* pass any_cost=True"):
        tessera.reproduce(tmp_path / "shells.png")


def test_reproduce_checks_the_recipe_before_the_image_as_the_cli_and_info_do(cli, tmp_path):
    # A recipe whose settings its scene does not give, on an image of another size than it
    # claims: Python's reproduce said `differs` (the image first) where the command line
    # refused the recipe; both take one check in one order now, and refuse it.
    small = tessera.render("scenes/cover.toml", width=40, spp=1)
    other = tessera.render("scenes/cover.toml", width=41, spp=1)
    recipe = json.loads(json.dumps(small.recipe))
    recipe["image"]["seed"] = 9
    (tmp_path / "both.png").write_bytes(_png_with_recipe(other.png(), recipe))
    with pytest.raises(tessera.TesseraError, match="seed 9, the scene gives"):
        tessera.reproduce(tmp_path / "both.png")
    for args in (("info", tmp_path / "both.png"), ("reproduce", tmp_path / "both.png", "-q")):
        said = cli(*args, check=False)
        assert said.returncode == 2 and "seed 9, the scene gives" in said.stderr, said
    # Its own recipe on the image of another size: `differs` from each, without a render.
    (tmp_path / "cropped.png").write_bytes(_png_with_recipe(other.png(), small.recipe))
    verdict = tessera.reproduce(tmp_path / "cropped.png")
    assert verdict["verdict"] == "differs", verdict
    assert "x" in verdict["summary"] and "its recipe makes 40x" in verdict["summary"], verdict
    info = json.loads(cli("info", "--json", tmp_path / "cropped.png").stdout)
    assert info["differs"]["summary"] == verdict["summary"]


def test_reproduce_refuses_what_has_no_recipe(cli, tmp_path):
    cli("render", "scenes/cover.toml", "--width", 16, "--spp", 1, "--no-provenance", "-q",
        "-o", tmp_path / "bare.png")
    with pytest.raises(tessera.TesseraError, match="no recipe"):
        tessera.reproduce(tmp_path / "bare.png")
    (tmp_path / "junk.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\xff" * 64)
    with pytest.raises(tessera.TesseraError):
        tessera.reproduce(tmp_path / "junk.png")
    with pytest.raises(FileNotFoundError):
        tessera.reproduce(tmp_path / "none.png")


# A recipe over the 1 MiB every reader takes is left out, with a warning, as the CLI does.
def test_a_scene_too_long_for_a_recipe_saves_without_one_and_warns(tmp_path):
    text = (ROOT / "scenes" / "img-1.03-red-sphere.toml").read_text()
    image = tessera.render(text + "# " + "x" * (1 << 20) + "\n", width=16, spp=1)
    for name in ["long.png", "long.exr"]:
        with pytest.warns(UserWarning, match="an image may carry, so the image carries none"):
            image.save(tmp_path / name)
        with pytest.raises(tessera.TesseraError, match="no recipe"):
            tessera.reproduce(tmp_path / name)
    with pytest.warns(UserWarning, match="an image may carry"):
        assert image.png().startswith(b"\x89PNG")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        image.save(tmp_path / "long.ppm")


def test_bench_gives_a_valid_result_the_cli_imports(cli, tmp_path):
    result = tessera.bench("quick", threads=1, repeat=1, warmup=0)
    assert result["schema"].startswith("tessera-bench/")
    assert result["workload"]["name"] == "quick"
    assert result["validation"]["status"] == "valid", result["validation"]
    assert result["result"]["threads"] == 1 and result["result"]["samples_per_sec"]["median"] > 0
    with pytest.raises(ValueError, match="workload"):
        tessera.bench("no-such-workload")
    with pytest.raises(ValueError, match="repeat must be a whole number from 1"):
        tessera.bench("quick", repeat=0)
    # Saved as JSON, the command line imports it, and results() reads it back.
    (tmp_path / "quick.json").write_text(json.dumps(result))
    db = tmp_path / "results.db"
    cli("results", "import", tmp_path / "quick.json", "--db", db)
    runs = tessera.results(db)
    assert len(runs) == 1
    run = runs[0]
    assert run["workload"] == "quick" and run["threads"] == 1 and run["validation"] == "valid"
    assert run["result"] == result
    assert run["samples_per_second"] == result["result"]["samples_per_sec"]["median"]
    assert tessera.results(db, workload="cover") == []
    listed = cli("results", "list", "--db", db).stdout
    assert str(run["id"]) in listed


def test_results_of_a_missing_or_foreign_database_raise(tmp_path, monkeypatch):
    with pytest.raises(tessera.TesseraError, match="no results database yet"):
        tessera.results(tmp_path / "none.db")
    (tmp_path / "other.db").write_bytes(b"not a database at all" * 100)
    with pytest.raises(tessera.TesseraError):
        tessera.results(tmp_path / "other.db")
    monkeypatch.setenv("TESSERA_DB", str(tmp_path / "env.db"))
    with pytest.raises(tessera.TesseraError, match="env.db"):
        tessera.results()


def test_results_frame_is_a_table_of_the_runs(cli, tmp_path):
    pandas = pytest.importorskip("pandas")
    result = tessera.bench("quick", threads=1, repeat=1, warmup=0)
    (tmp_path / "quick.json").write_text(json.dumps(result))
    db = tmp_path / "results.db"
    cli("results", "import", tmp_path / "quick.json", "--db", db)
    frame = tessera.results_frame(db)
    assert isinstance(frame, pandas.DataFrame) and len(frame) == 1
    assert frame.loc[0, "workload"] == "quick"
    assert str(frame["started"].dt.tz) == "UTC"


# tessera's first schema, as a database someone else made may have it (the file the Rust
# tests read too).
FIRST_SCHEMA = (ROOT / "tests" / "data" / "results-schema-1.sql").read_text()


@pytest.mark.parametrize("result", ["{not json", "[" * 100_000 + "]" * 100_000])
def test_results_with_a_result_that_is_not_json_raise_tessera_error(tmp_path, result):
    # Once a JSONDecodeError, or a RecursionError, rather than tessera's own.
    import sqlite3

    # Its name, anyone's in a shared directory, quoted escaped.
    db = tmp_path / "made\x1b[2J\u202e.db"
    conn = sqlite3.connect(db)
    conn.executescript(FIRST_SCHEMA)
    conn.execute(
        "INSERT INTO runs VALUES (1, 'd', 1, 'import', 1700000000, 'm-0', 'Old CPU', 4, "
        "'0.1.0', 'abc', 'avx2', 'cover', 'id', 4, 1e6, 9e5, 1.1e6, 'valid', ?)",
        (result,),
    )
    conn.commit()
    conn.close()
    # Refused in Rust, as it checks each run against its result: the message escaped as
    # every message of tessera's is.
    with pytest.raises(tessera.TesseraError, match="run 1: its result: not JSON") as e:
        tessera.results(db)
    assert "made\\u{1b}[2J\\u{202e}.db: run 1" in str(e.value), str(e.value)


# A database held locked by another process (a colleague's, writing it; one of theirs left
# in a transaction) is waited for, 30 s for each of two statements: with the interpreter's
# lock released but no look at Ctrl-C, `results` once sat out all 60 s after it.
WAITING_FOR_A_LOCK = """
import sys, tessera
print("reading", flush=True)
try:
    tessera.results(sys.argv[1])
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(0)
sys.exit(3)
"""


def test_ctrl_c_stops_results_waiting_for_a_locked_database(tmp_path):
    import signal
    import sqlite3
    import subprocess
    import sys
    import time

    db = tmp_path / "locked.db"
    conn = sqlite3.connect(db, isolation_level=None)
    conn.executescript(FIRST_SCHEMA)
    conn.execute("BEGIN EXCLUSIVE")
    child = subprocess.Popen(
        [sys.executable, "-c", WAITING_FOR_A_LOCK, str(db)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=as_at_a_terminal,
    )
    try:
        assert child.stdout.readline().strip() == "reading"
        time.sleep(1.0)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        rest, _ = child.communicate(timeout=90)
        took = time.monotonic() - sent
    finally:
        child.kill()
        conn.close()
    assert (child.returncode, rest.strip()) == (0, "interrupted")
    assert took < 1.5, took
