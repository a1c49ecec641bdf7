"""tessera.render against the command line: the same pixels and the same files for the cover
and every figure scene, whatever the threads or SIMD path; progressive passes; Ctrl-C; and
what the renders return."""

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

import tessera
from conftest import ROOT, as_at_a_terminal, read_ppm

SCENES = sorted(p.name for p in (ROOT / "scenes").glob("*.toml"))
# Small enough that every scene renders in a fraction of a second.
WIDTH, SPP = 40, 2


def test_every_scene_is_tested():
    assert "cover.toml" in SCENES and "img-2.22-book2-final.toml" in SCENES
    assert len(SCENES) >= 40, SCENES


@pytest.mark.parametrize("name", SCENES)
def test_pixels_and_file_are_the_command_lines(name, cli, tmp_path):
    scene = f"scenes/{name}"
    image = tessera.render(scene, width=WIDTH, spp=SPP)
    cli("render", scene, "--width", WIDTH, "--spp", SPP, "-q", "-o", tmp_path / "cli.ppm")
    width, height, values = read_ppm(tmp_path / "cli.ppm")
    assert (image.width, image.height) == (width, height)
    assert image.srgb8.shape == (height, width, 3) and image.srgb8.dtype == np.uint8
    assert image.srgb8.tobytes() == values
    # The file, recipe included, byte for byte.
    cli("render", scene, "--width", WIDTH, "--spp", SPP, "-q", "-o", tmp_path / "cli.png")
    image.save(tmp_path / "py.png")
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    assert image.png() == (tmp_path / "cli.png").read_bytes()


def test_exr_and_ppm_files_are_the_command_lines(cli, tmp_path):
    image = tessera.render("scenes/cover.toml", width=60, spp=3, seed=7, depth=9)
    for ext in ("exr", "ppm"):
        cli("render", "scenes/cover.toml", "--width", 60, "--spp", 3, "--seed", 7, "--depth", 9,
            "-q", "-o", tmp_path / f"cli.{ext}")
        image.save(tmp_path / f"py.{ext}")
        assert (tmp_path / f"py.{ext}").read_bytes() == (tmp_path / f"cli.{ext}").read_bytes()


def test_linear_is_the_exr_the_command_line_writes(cli, tmp_path):
    image = tessera.render("scenes/img-2.20-cornell-standard.toml", width=30, spp=4)
    linear = image.linear
    assert linear.shape == (image.height, image.width, 3) and linear.dtype == np.float32
    assert not linear.flags.writeable
    assert np.isfinite(linear).all() and linear.min() >= 0
    assert abs(float(linear.mean(dtype=np.float64)) - image.mean_radiance) < 1e-5
    # The PNG's pixels are the linear values tone-mapped.
    shown = np.clip(np.sqrt(linear), 0, 0.999) * 256
    assert np.abs(shown.astype(np.int32) - image.srgb8.astype(np.int32)).max() <= 1


def test_threads_and_simd_paths_give_the_same_arrays():
    paths, best = tessera.simd_paths()
    assert paths[0] == "portable" and best in paths
    base = tessera.render("scenes/cover.toml", width=64, spp=3, threads=1, simd="portable")
    for threads in (1, 2, 3):
        for path in paths + ["auto"]:
            other = tessera.render("scenes/cover.toml", width=64, spp=3, threads=threads, simd=path)
            assert np.array_equal(other.linear, base.linear), (threads, path)
            assert np.array_equal(other.srgb8, base.srgb8)
            assert other.sums == base.sums
            assert other.stats["threads"] == threads
            assert other.stats["simd"] == (best if path == "auto" else path)


def test_a_scene_as_text_or_dict_renders_as_its_file():
    path = ROOT / "scenes" / "cover.toml"
    from_file = tessera.render(path, width=48, spp=2)
    from_text = tessera.render(path.read_text(), width=48, spp=2)
    with open(path, "rb") as f:
        from_dict = tessera.render(tomllib.load(f), width=48, spp=2)
    assert from_file.sums == from_text.sums == from_dict.sums
    assert from_file.recipe["scene"]["name"] == "cover.toml"
    assert from_text.recipe["scene"]["name"] == "<string>"
    assert from_dict.recipe["scene"]["name"] == "<dict>"
    # NumPy numbers in a dict are numbers.
    scene = {
        "image": {"width": np.int64(40), "height": 20, "samples_per_pixel": 2,
                  "max_depth": 4, "seed": np.uint64(3)},
        "materials": {"grey": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
        "spheres": [
            {"center": np.array([0.0, 0.0, -1.0]), "radius": np.float32(0.5),
             "material": "grey"},
            {"center": (0, -100.5, -1), "radius": 100, "material": "grey"},
        ],
    }
    assert tessera.render(scene).width == 40


def test_overrides_are_the_command_lines_flags():
    image = tessera.render("scenes/cover.toml", width=30, spp=3, depth=5, seed=11)
    assert (image.width, image.samples_per_pixel, image.max_depth, image.seed) == (30, 3, 5, 11)
    assert image.recipe["overrides"] == {
        "width": 30, "samples_per_pixel": 3, "max_depth": 5, "seed": 11,
    }
    other_seed = tessera.render("scenes/cover.toml", width=30, spp=3, depth=5, seed=12)
    assert other_seed.sums != image.sums


def test_on_pass_sees_each_pass_and_the_same_final_image():
    seen = []

    def on_pass(image):
        seen.append((image.samples_per_pixel, image.sums, image.srgb8.copy()))

    final = tessera.render("scenes/cover.toml", width=48, spp=20, on_pass=on_pass)
    plain = tessera.render("scenes/cover.toml", width=48, spp=20)
    assert [s for s, _, _ in seen] == [1, 4, 16, 20]
    assert final.sums == plain.sums == seen[-1][1]
    assert np.array_equal(seen[-1][2], plain.srgb8)
    # A pass's image is the render of that many samples, and says so in its recipe.
    four = tessera.render("scenes/cover.toml", width=48, spp=4)
    assert seen[1][1] == four.sums
    assert final.stats is not None


def test_a_pass_image_saved_reproduces(tmp_path):
    kept = []
    tessera.render("scenes/cover.toml", width=32, spp=8, on_pass=kept.append)
    kept[1].save(tmp_path / "pass.png")
    assert kept[1].stats is None
    verdict = tessera.reproduce(tmp_path / "pass.png")
    assert verdict["verdict"] == "identical", verdict


def test_what_on_pass_raises_stops_the_render_and_is_raised():
    calls = []

    def on_pass(image):
        calls.append(image.samples_per_pixel)
        raise LookupError("enough")

    with pytest.raises(LookupError, match="enough"):
        tessera.render("scenes/cover.toml", width=48, spp=64, on_pass=on_pass)
    assert calls == [1]


def test_other_threads_run_while_it_renders():
    ticks = []
    running = threading.Event()

    def tick():
        while not running.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.01)

    thread = threading.Thread(target=tick)
    thread.start()
    try:
        started = time.monotonic()
        tessera.render("scenes/cover.toml", width=200, spp=16, threads=1)
        took = time.monotonic() - started
    finally:
        running.set()
        thread.join()
    during = [t for t in ticks if started <= t <= started + took]
    # Ticks every 10 ms while the lock is free: at least a third of them.
    assert len(during) >= took / 0.01 / 3, (len(during), took)


@contextlib.contextmanager
def ticking():
    """A thread that counts a tick every 5 ms while the interpreter's lock lets it: yields
    the count (its one item), and stops the thread at the end."""
    ticks = [0]
    done = threading.Event()

    def tick():
        while not done.is_set():
            time.sleep(0.005)
            ticks[0] += 1

    thread = threading.Thread(target=tick)
    thread.start()
    try:
        yield ticks
    finally:
        done.set()
        thread.join()


# Of a 6000x4000 image, `linear`, `srgb8` and `sums` once held the interpreter's lock for
# 0.76, 0.56 and 0.23 s, every other thread held up as long.
def test_other_threads_run_while_an_image_s_arrays_are_made():
    image = tessera.render("scenes/cover.toml", width=6000, spp=1, depth=1)
    took = {}
    with ticking() as ticks:
        for name in ("linear", "srgb8", "sums"):
            time.sleep(0.05)
            before, started = ticks[0], time.monotonic()
            getattr(image, name)
            took[name] = (time.monotonic() - started, ticks[0] - before)
    # A call that holds the interpreter's lock throughout lets the other thread tick at most
    # once (it wakes, then waits for the lock until the call returns); one that releases it
    # lets it tick along. Counted, not timed: a loaded machine slows both alike. The linear
    # pixels of 6000x3375 take a tenth of a second or more on any machine.
    assert took["linear"][0] >= 0.1, took
    for name, (seconds, ticked) in took.items():
        if seconds >= 0.1:
            assert ticked >= 3, (name, seconds, ticked)


# The recipe of a scene given as 60 MB of text (a long comment) holds that text: its JSON was
# once written with the interpreter's lock held, every other thread held up 0.5 s.
def test_other_threads_run_while_an_image_s_recipe_is_written():
    with open(ROOT / "scenes" / "cover.toml") as f:
        text = "# " + "x" * (60 << 20) + "\n" + f.read()
    image = tessera.render(text, width=8, spp=1)
    with ticking() as ticks:
        time.sleep(0.05)
        before, started = ticks[0], time.monotonic()
        recipe = image._native.recipe
        seconds, ticked = time.monotonic() - started, ticks[0] - before
    assert len(recipe) > 60 << 20
    if seconds >= 0.1:
        assert ticked >= 3, (seconds, ticked)


# Forked after a render, as `multiprocessing` does on Linux, a process once inherited rayon's
# global pool without its threads, and its first render waited for them forever.
FORKED = textwrap.dedent(
    """
    import multiprocessing, tessera
    def sums(_):
        return tessera.render("scenes/cover.toml", width=24, spp=2).sums
    before = sums(0)
    with multiprocessing.get_context("fork").Pool(2) as pool:
        print(pool.map_async(sums, range(2)).get(timeout=60) == [before] * 2, flush=True)
    """
)


def test_a_process_forked_after_a_render_renders():
    done = subprocess.run(
        [sys.executable, "-c", FORKED], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "True"


# Forked by `on_pass` while the render's thread runs, as a child that saves a pass in the
# background may be, the child waited forever for a render whose thread is the parent's.
FORKED_IN_ON_PASS = textwrap.dedent(
    """
    import os, tessera
    child = False
    def on_pass(image):
        global child
        if image.samples_per_pixel == 1 and os.fork() == 0:
            child = True
    try:
        result = tessera.render("scenes/cover.toml", width=48, spp=64, on_pass=on_pass).sums
    except tessera.TesseraError as e:
        result = f"refused: {e}"
    if child:
        print("child", result, flush=True)
        os._exit(0)
    os.wait()
    print("parent", result == tessera.render("scenes/cover.toml", width=48, spp=64).sums)
    """
)


def test_a_process_forked_by_on_pass_is_told_not_left_waiting():
    child = subprocess.Popen(
        [sys.executable, "-c", FORKED_IN_ON_PASS],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        out, err = child.communicate(timeout=60)
    finally:
        # The whole group: a child left waiting, too.
        try:
            os.killpg(child.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert child.returncode == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("child refused: this process was forked during the render"), out
    assert lines[1] == "parent True", out


INTERRUPTED = textwrap.dedent(
    """
    import asyncio, signal, sys, time, tessera
    BEFORE
    print("rendering", flush=True)
    started = time.monotonic()
    try:
        CALL
    except KeyboardInterrupt:
        print("interrupted", flush=True)
        sys.exit(0)
    sys.exit(3)
    """
)


# A benchmark renders too: it once went on to its last render after Ctrl-C (the cover's,
# one thread, twice: 191 s).
# Python's handler of Ctrl-C, installed again after a first render (`asyncio.run` installs
# one and restores the default), once replaced tessera's own: every later render went on to
# its end.
@pytest.mark.parametrize(
    "before, call",
    [
        ("", 'tessera.render("scenes/cover.toml", spp=1_000_000)'),
        ("", 'tessera.bench("cover", threads=1, repeat=1000, warmup=0)'),
        (
            'tessera.render("scenes/cover.toml", width=8, spp=1); asyncio.run(asyncio.sleep(0))',
            'tessera.render("scenes/cover.toml", spp=1_000_000)',
        ),
    ],
    ids=["render", "bench", "render-after-asyncio"],
)
def test_ctrl_c_stops_a_long_render_within_a_second(before, call):
    script = INTERRUPTED.replace("BEFORE", before).replace("CALL", call)
    child = subprocess.Popen(
        [sys.executable, "-c", script],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=as_at_a_terminal,
    )
    try:
        assert child.stdout.readline().strip() == "rendering"
        time.sleep(1.5)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        rest, _ = child.communicate(timeout=30)
        took = time.monotonic() - sent
    finally:
        child.kill()
    assert child.returncode == 0, child.returncode
    assert rest.strip() == "interrupted"
    assert took < 1.0, took


# Off the main thread, Ctrl-C stops a render too; once Python's handler of it was installed
# again after a first such render (as `asyncio.run` installs and restores one), a render on a
# thread went on to its end (60 s and more) while the main thread took its KeyboardInterrupt.
OFF_THE_MAIN_THREAD = textwrap.dedent(
    """
    import os, signal, threading, time, tessera
    def render(spp, said):
        try:
            tessera.render("scenes/cover.toml", width=64, spp=spp)
            said.append("finished")
        except KeyboardInterrupt:
            said.append("interrupted")
    first = []
    thread = threading.Thread(target=render, args=(1, first)); thread.start(); thread.join()
    signal.signal(signal.SIGINT, signal.default_int_handler)
    said = []
    thread = threading.Thread(target=render, args=(1_000_000, said), daemon=True)
    thread.start()
    time.sleep(1.0)
    sent = time.monotonic()
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(10)
    except KeyboardInterrupt:
        pass
    thread.join(10)
    print(first, said, time.monotonic() - sent < 1.5, flush=True)
    """
)


def test_ctrl_c_stops_a_render_off_the_main_thread_after_python_s_handler_is_installed_again():
    done = subprocess.run(
        [sys.executable, "-c", OFF_THE_MAIN_THREAD],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "['finished'] ['interrupted'] True", done.stdout


# Python's handler of Ctrl-C installed again on the main thread during a render on a thread
# (as `asyncio.run` installs one as it begins) took the place of tessera's: the thread's render
# went on to its end after Ctrl-C (still running 60 s later).
REPLACED_DURING = textwrap.dedent(
    """
    import os, signal, threading, time, tessera
    BEFORE
    said = []
    def render():
        try:
            tessera.render("scenes/cover.toml", width=64, spp=1_000_000)
            said.append("finished")
        except KeyboardInterrupt:
            said.append("interrupted")
    thread = threading.Thread(target=render, daemon=True)
    thread.start()
    time.sleep(0.5)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    time.sleep(0.5)
    sent = time.monotonic()
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(10)
    except KeyboardInterrupt:
        pass
    thread.join(10)
    print(said, time.monotonic() - sent < 1.5, flush=True)
    """
)


# Begun while Python ignored Ctrl-C, a render on a thread went on to its end after Ctrl-C
# once a handler was installed during it (still running 5 s later), as the main thread took
# its KeyboardInterrupt.
@pytest.mark.parametrize(
    "before",
    ["", "signal.signal(signal.SIGINT, signal.SIG_IGN)"],
    ids=["replaced", "ignored-before"],
)
def test_ctrl_c_stops_a_render_on_a_thread_when_python_s_handler_is_installed_during_it(before):
    done = subprocess.run(
        [sys.executable, "-c", REPLACED_DURING.replace("BEFORE", before)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "['interrupted'] True", done.stdout


# A handler of Ctrl-C that calls the one it replaced, as a C library's may, installed after
# a render on a thread (so in the place of tessera's): the next render on a thread put
# tessera's in place again, which called that one, which called tessera's, and so on until
# the stack overflowed: a segfault at the first Ctrl-C.
CHAINS = r"""
#include <signal.h>
#include <string.h>
static struct sigaction replaced;
static volatile sig_atomic_t calls;
static void chained(int signal, siginfo_t *info, void *context) {
    calls++;
    if (replaced.sa_flags & SA_SIGINFO)
        replaced.sa_sigaction(signal, info, context);
    else if (replaced.sa_handler != SIG_DFL && replaced.sa_handler != SIG_IGN)
        replaced.sa_handler(signal);
}
int install(void) {
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_sigaction = chained;
    action.sa_flags = SA_SIGINFO;
    sigemptyset(&action.sa_mask);
    return sigaction(SIGINT, &action, &replaced);
}
int calls_seen(void) { return calls; }
"""

CHAINED = textwrap.dedent(
    """
    import ctypes, os, signal, sys, threading, time, tessera
    # Python's own handler, whatever this process inherited (a shell's background job
    # starts with Ctrl-C ignored, and Python then installs none).
    signal.signal(signal.SIGINT, signal.default_int_handler)
    chains = ctypes.CDLL(sys.argv[1])
    def render(spp, said):
        try:
            tessera.render("scenes/cover.toml", width=64, spp=spp)
            said.append("finished")
        except KeyboardInterrupt:
            said.append("interrupted")
    first = []
    thread = threading.Thread(target=render, args=(1, first)); thread.start(); thread.join()
    assert chains.install() == 0
    said = []
    thread = threading.Thread(target=render, args=(1_000_000, said), daemon=True)
    thread.start()
    time.sleep(1.0)
    main = "went on"
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(10)
    except KeyboardInterrupt:
        main = "interrupted"
    thread.join(10)
    print(first, said, main, chains.calls_seen(), flush=True)
    """
)


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_ctrl_c_reaches_a_handler_that_calls_tessera_s_once(tmp_path):
    (tmp_path / "chains.c").write_text(CHAINS)
    library = tmp_path / "libchains.so"
    subprocess.run(
        ["cc", "-shared", "-fPIC", "-o", library, tmp_path / "chains.c"], check=True
    )
    done = subprocess.run(
        [sys.executable, "-c", CHAINED, library],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, (done.returncode, done.stderr)
    assert done.stdout.strip() == "['finished'] ['interrupted'] interrupted 1", done.stdout


# Ignored (SIG_IGN), Ctrl-C once stopped a render all the same and raised KeyboardInterrupt.
IGNORED = textwrap.dedent(
    """
    import os, signal, threading, tessera
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
    image = tessera.render("scenes/cover.toml", width=160, spp=64, threads=1)
    print(image.sums == tessera.render("scenes/cover.toml", width=160, spp=64).sums)
    """
)


def test_an_ignored_ctrl_c_stops_nothing():
    done = subprocess.run(
        [sys.executable, "-c", IGNORED], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "True"


def test_what_a_signal_handler_raises_stops_a_render_and_is_raised():
    def alarm(signum, frame):
        raise TimeoutError("past its time")

    previous = signal.signal(signal.SIGALRM, alarm)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.3)
        started = time.monotonic()
        with pytest.raises(TimeoutError, match="past its time"):
            tessera.render("scenes/cover.toml", spp=1_000_000)
        assert time.monotonic() - started < 1.3
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_an_image_shows_in_a_notebook():
    image = tessera.render("scenes/cover.toml", width=24, spp=1)
    png = image._repr_png_()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and b"tessera-recipe" in png
    assert "24x16" in repr(image)


def test_help_says_what_to_pass():
    doc = tessera.render.__doc__
    for word in ("scene", "width", "spp", "depth", "seed", "threads", "simd", "on_pass",
                 "SceneError", "KeyboardInterrupt"):
        assert word in doc, word
    stubs = Path(tessera.__file__).with_name("_native.pyi")
    assert stubs.exists() and "def render(" in stubs.read_text()
    assert Path(tessera.__file__).with_name("py.typed").exists()


def test_the_build_is_this_checkout():
    build = tessera.build()
    assert build["version"] == tessera.__version__
    assert len(build["commit"].split("-")[0]) == 40 or build["commit"] == "unknown"
    assert os.path.basename(tessera.__file__) == "__init__.py"


# Ctrl-C while a scene is built (a cloud of 2^20 spheres: drawn, then a tree built over them,
# where no look at Ctrl-C reaches) was raised only once the build had ended, 9 s later on a
# 2-core machine. It is raised while the build goes on, on its own thread, which then ends by
# itself: the order is what is checked, not a time.
BUILDING = textwrap.dedent(
    """
    import os, signal, threading, time, tessera
    def building():
        tasks = os.listdir("/proc/self/task")
        names = []
        for task in tasks:
            try:
                with open(f"/proc/self/task/{task}/comm") as comm:
                    names.append(comm.read().strip())
            except OSError:
                pass
        return "tessera-render" in names
    scene = '''
    [image]
    width = 8
    height = 8
    samples_per_pixel = 1
    max_depth = 2
    [camera]
    lookfrom = [0.0, 0.0, 400.0]
    lookat = [0.0, 0.0, 0.0]
    vfov_deg = 40.0
    [materials.grey]
    type = "lambertian"
    albedo = [0.5, 0.5, 0.5]
    [[random_sphere_clouds]]
    count = 1048576
    min = [0.0, 0.0, 0.0]
    max = [165.0, 165.0, 165.0]
    radius = 1.0
    material = "grey"
    '''
    threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)).start()
    try:
        tessera.render(scene)
        print("finished", flush=True)
    except KeyboardInterrupt:
        print("interrupted while building", building(), flush=True)
    while building():
        time.sleep(0.05)
    print("then it ended", flush=True)
    """
)


def test_ctrl_c_is_raised_while_a_large_scene_is_still_being_built():
    done = subprocess.run(
        [sys.executable, "-c", BUILDING],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=as_at_a_terminal,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["interrupted while building True", "then it ended"], (
        done.stdout
    )
