"""What a user (or a stranger's file) can get wrong: each is an exception with the command
line's message, and the interpreter goes on; a panic in Rust is an exception too."""

import itertools
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import tessera
from conftest import ROOT, as_at_a_terminal


def test_a_scene_error_says_file_line_column_and_field(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text("[image]\nwidth = 40\nheight = 20\nsamples_per_pixel = 0\nmax_depth = 2\n")
    with pytest.raises(tessera.SceneError) as e:
        tessera.render(scene)
    err = e.value
    assert isinstance(err, tessera.TesseraError) and isinstance(err, Exception)
    assert (err.file, err.line, err.column) == (str(scene), 4, 21)
    assert err.field == "image.samples_per_pixel"
    assert str(err).startswith(f"{scene}:4:21: field `image.samples_per_pixel`")


def test_a_syntax_error_in_text_names_the_string():
    with pytest.raises(tessera.SceneError) as e:
        tessera.render("[image]\nwidth = = 3\n")
    assert e.value.file == "<string>" and e.value.line == 2 and e.value.field is None
    with pytest.raises(tessera.SceneError, match=r"<string>:2:1: field `camera.foo`: unknown") as e:
        tessera.render("[camera]\nfoo = 1\n")
    assert e.value.field == "camera.foo"


@pytest.mark.parametrize(
    "kwargs, says",
    [
        ({"spp": -5}, "spp must be a whole number from 1 to 4294967295, got -5"),
        ({"spp": 0}, "spp must be a whole number from 1 to"),
        ({"width": 2**40}, "width must be a whole number from 1 to 4294967295"),
        ({"seed": -1}, "seed must be a whole number from 0 to 18446744073709551615"),
        ({"seed": 2**64}, "seed must be a whole number from 0 to"),
        ({"threads": 0}, "threads must be a whole number from 1 to 4096"),
        ({"threads": 5000}, "threads must be a whole number from 1 to 4096"),
        ({"depth": 1.5}, "depth must be a whole number"),
        ({"spp": True}, "spp must be a whole number"),
        ({"spp": "16"}, "spp must be a whole number"),
        ({"simd": "neon"}, "simd: unknown SIMD path `neon`"),
        ({"simd": 3}, "simd must be a SIMD path's name"),
        ({"width": 1_000_000}, "pixels"),
    ],
)
def test_a_bad_argument_is_a_value_error(kwargs, says):
    with pytest.raises(ValueError, match=None) as e:
        tessera.render("scenes/cover.toml", **{"spp": 1, "width": 8, **kwargs})
    assert says in str(e.value), str(e.value)


def test_a_missing_or_odd_scene_is_refused(tmp_path):
    with pytest.raises(FileNotFoundError, match="scenes/covr.toml: no such scene file"):
        tessera.render("scenes/covr.toml")
    with pytest.raises(TypeError, match="scene must be a path"):
        tessera.render(b"scenes/cover.toml")
    with pytest.raises(TypeError, match="scene must be a path"):
        tessera.render(42)
    with pytest.raises(ValueError, match="NUL"):
        tessera.render("scenes/cover\0.toml")
    with pytest.raises(OSError):
        tessera.render(tmp_path)
    fifo = tmp_path / "scene.toml"
    os.mkfifo(fifo)
    with pytest.raises(tessera.TesseraError if False else OSError, match="not a regular file"):
        tessera.render(fifo)
    with pytest.raises(TypeError, match="on_pass must be callable"):
        tessera.render("scenes/cover.toml", on_pass=3)


@pytest.mark.parametrize(
    "scene, says",
    [
        ({"image": None}, "invalid setting `scene`"),
        ({"image": {"width": float("nan")}}, "Out of range float"),
        ({"image": {"width": 1e400}}, "Out of range float"),
        ({1: 2}, "a dict's keys must be strings"),
        ({"image": {"width": object()}}, "object is none of them"),
        # A NumPy date or time span in nanoseconds, whose `item()` is an int, was that int.
        ({"image": {"width": np.datetime64(8, "ns")}}, "datetime64 is none of them"),
        ({"image": {"width": np.timedelta64(8, "ns")}}, "timedelta64 is none of them"),
        ({"spheres": "many"}, "spheres"),
        ({"image": {"width": 10**30, "height": 2}}, "image.width"),
        # Beyond TOML's whole numbers: named by the keys, not by a place in JSON.
        ({"image": {"width": 2**63}}, "image.width is 9223372036854775808, beyond"),
        ({"spheres": [{"center": [0, 2**64, 0]}]}, "spheres[0].center[1] is 1844"),
        ({"image": {"width": np.uint64(2**64 - 1)}}, "image.width is 1844"),
        # NumPy arrays: counted as the values they write out before they are (one number
        # broadcast to 2^26 once took 15 s and 3 GB to write out, then to be refused), their
        # whole numbers checked, their objects (unchecked dicts) refused.
        (
            {"spheres": [{"center": np.broadcast_to(np.float64(0.5), (1 << 40,))}]},
            "spheres[0].center is a NumPy array of shape (1099511627776,), written out as more",
        ),
        # An empty array is written out as its lists: 10^7 x 0 once took 6.7 s and 750 MB of
        # empty lists, 10^9 x 0 all the memory there was.
        (
            {"spheres": np.empty((10**9, 0))},
            "spheres is a NumPy array of shape (1000000000, 0), written out as more",
        ),
        ({"image": {"width": np.array([2**64 - 1], dtype=np.uint64)}}, "holds 1844"),
        ({"spheres": [{"center": np.array([{1: 2}], dtype=object)}]}, "array of object"),
    ],
)
def test_a_bad_dict_is_refused(scene, says):
    with pytest.raises((ValueError, tessera.SceneError)) as e:
        tessera.render(scene)
    assert says in str(e.value), str(e.value)


def _holding_itself():
    scene = {"image": {"width": 8}}
    scene["image"]["self"] = scene
    return scene


def _list_holding_itself_twice():
    twice: list = []
    twice += [twice, twice]
    return {"image": twice}


def _one_list_held_2_to_the_40_times():
    shared: list = [1]
    for _ in range(40):
        shared = [shared, shared]
    return {"spheres": shared}


def test_a_dict_s_keys_reach_a_python_side_message_escaped_and_bounded():
    # A dict loaded from a stranger's JSON: its keys once reached the message raw.
    with pytest.raises(ValueError) as e:
        tessera.render({"image": {"w\x1b]0;owned\x07\u202e": 2**64}})
    assert "image.w\\x1b]0;owned\\x07\\u202e is 18446744073709551616" in str(e.value)
    with pytest.raises(ValueError) as e:
        tessera.render({"s\x1b[2J": [np.array([{1: 2}], dtype=object)]})
    assert str(e.value).startswith("scene: s\\x1b[2J[0] is a NumPy array of object")
    with pytest.raises(ValueError) as e:
        tessera.render({"k" * 1_000_000: {"a": 2**64}})
    assert len(str(e.value)) < 600 and "kkk…kkk" in str(e.value)
    assert "kkk.a is 18446744073709551616" in str(e.value)


def test_numpy_long_doubles_in_a_dict_are_its_floats():
    # `item()` and `tolist()` leave a long double NumPy's: once a RecursionError.
    def scene(center):
        return {
            "image": {"width": 8, "height": 8, "samples_per_pixel": 1, "max_depth": 2},
            "materials": {"m": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
            "spheres": [{"center": center, "radius": 0.5, "material": "m"}],
        }

    expected = tessera.render(scene([0.0, 0.0, -1.0])).sums
    assert tessera.render(scene([np.longdouble(0), 0.0, -1.0])).sums == expected
    assert tessera.render(scene(np.array([0, 0, -1], dtype=np.longdouble))).sums == expected
    with pytest.raises(ValueError, match="clongdouble is none of them"):
        tessera.render(scene([np.clongdouble(0), 0.0, -1.0]))


def test_a_path_of_any_bytes_is_taken_and_quoted_escaped(tmp_path):
    # A scene file's name that is not UTF-8 once raised UnicodeEncodeError, and a path given
    # as bytes to save or results "'bytes' object is not an instance of 'str'".
    odd = os.path.join(os.fsencode(tmp_path), b"cover-\xff.toml")
    with open(odd, "wb") as f:
        f.write((ROOT / "scenes" / "cover.toml").read_bytes())
    expected = tessera.render("scenes/cover.toml", width=16, spp=1)
    image = tessera.render(Path(os.fsdecode(odd)), width=16, spp=1)
    assert image.sums == expected.sums
    assert tessera.render(os.fsdecode(odd), width=16, spp=1).sums == expected.sums
    image.save(os.path.join(os.fsencode(tmp_path), b"out-\xfe.png"))
    assert (tmp_path / os.fsdecode(b"out-\xfe.png")).read_bytes() == image.png()
    with pytest.raises(tessera.TesseraError, match="no results database yet"):
        tessera.results(os.path.join(os.fsencode(tmp_path), b"none.db"))
    # A missing file's name, which anyone may have chosen in a shared directory, is quoted
    # with its control and bidirectional characters escaped.
    with pytest.raises(FileNotFoundError) as e:
        tessera.render(str(tmp_path / "\x1b]0;owned\x07\u202e.toml"))
    assert "\\x1b]0;owned\\x07\\u202e.toml: no such scene file" in str(e.value)
    assert not any(c in str(e.value) for c in "\x1b\x07\u202e"), str(e.value)


def _nested(empty, depth):
    inner = 1
    for _ in range(depth):
        inner = {"a": inner} if isinstance(empty, dict) else [inner]
    return inner


class _EndlessItems(dict):
    def items(self):
        return ((f"k{i}", i) for i in itertools.count())


class _EndlessList(list):
    def __iter__(self):
        return itertools.repeat(1)


@pytest.mark.parametrize(
    "make, says",
    [
        # The key check once walked these forever, the second growing by 8 MB a second.
        (_holding_itself, "a dict or list holds itself"),
        (_list_holding_itself_twice, "a dict or list holds itself"),
        # 2^40 lists written out: refused at the values a scene file may hold.
        (_one_list_held_2_to_the_40_times, "more than 1048576 values"),
        (lambda: {"a": ["x" * (1 << 20)] * 65}, "64 MiB of text"),
        # What a dict's items() or a list's iterator gives, once copied until it ended (never)
        # and then counted.
        (lambda: {"image": _EndlessItems()}, "more than 1048576 values"),
        (lambda: {"spheres": _EndlessList()}, "more than 1048576 values"),
        # Nested deeper than a scene's parser takes: once refused by a place in TOML or JSON
        # the user never wrote, or past a thousand levels by JSON's RecursionError.
        (lambda: {"image": _nested({}, 100_000)}, "image.a.a.a.a.a.a.a.a"),
        (lambda: {"image": _nested([], 200)}, "nests dicts and lists 65 deep, more than the 64"),
        # Written as TOML, each table's header repeats the keys above it: a long key over
        # 10,000 empty tables once wrote 10 GB (9.7 GB of memory, 86 s); and a float is
        # written without an exponent, 5e-324 in 326 bytes. Refused before it is written.
        (lambda: {"image": {"k" * 1_000_000: [{}] * 100}}, "it would take up to"),
        (lambda: {"x": [5e-324] * 300_000}, "it would take up to"),
    ],
)
def test_a_dict_that_holds_itself_or_writes_out_too_large_is_refused(make, says):
    with pytest.raises(ValueError) as e:
        tessera.render(make())
    assert says in str(e.value), str(e.value)
    # One dict held in many places is no cycle.
    shared = {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}
    scene = {
        "image": {"width": 8, "height": 8, "samples_per_pixel": 1, "max_depth": 2},
        "materials": {"a": shared, "b": shared},
        "spheres": [{"center": [0, 0, -1], "radius": 0.5, "material": "a"}],
    }
    assert tessera.render(scene).width == 8


def test_objects_that_say_other_than_they_hold_are_written_out_as_checked():
    # A str whose __len__ says 0 passed the bound on text: 700 of 1 MiB were written out as
    # JSON and TOML of 734 MB (6.7 s, 2.1 GB) before the bound on the TOML refused them.
    # What is written out is now a copy of plain values, made as they are counted.
    class Empty(str):
        def __len__(self):
            return 0

    class One(int):
        def __int__(self):
            return 1

        def __index__(self):
            return 1

    with pytest.raises(ValueError, match="64 MiB of text"):
        tessera.render({"x": [Empty("x" * (1 << 20))] * 700})
    with pytest.raises(ValueError, match=r"image\.width is 18446744073709551616, beyond"):
        tessera.render({"image": {"width": One(2**64)}})
    # What they hold is what is rendered.
    scene = {
        "image": {"width": 8, "height": 8, "samples_per_pixel": 1, "max_depth": 2},
        "materials": {"a": {"type": "lambertian", "albedo": [0.5, 0.5, 0.5]}},
        "spheres": [{"center": [0, 0, -1], "radius": 0.5, "material": "a"}],
    }
    lying = {
        "image": {"width": One(8), "height": 8, "samples_per_pixel": 1, "max_depth": 2},
        "materials": {Empty("a"): {"type": Empty("lambertian"), "albedo": [0.5, 0.5, 0.5]}},
        "spheres": [{"center": [0, 0, -1], "radius": 0.5, "material": Empty("a")}],
    }
    assert tessera.render(lying).sums == tessera.render(scene).sums


def test_a_long_key_above_many_dicts_is_not_written_out_for_each():
    # The key check kept each dict's place written out (`image.kkk…k[3]`) until it was
    # walked: 4,000 dicts under a key of a million characters once took 4 GB. Places are
    # written out for a message only.
    import tracemalloc

    scene = {"image": {"k" * 1_000_000: [{}] * 500}}
    tracemalloc.start()
    try:
        tessera._scene_input(scene)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50 << 20, f"{peak >> 20} MiB"
    # The places still name where a bad value is.
    with pytest.raises(ValueError, match=r"spheres\[1\]\.center\[2\] is 18446744073709551616"):
        tessera.render({"spheres": [{}, {"center": [0, 0, 2**64]}]})


HOSTILE_TEXTS = [
    # Tall: the width of 8 asked for below keeps the aspect, 8 x 799999992 pixels.
    "[image]\nwidth = 1\nheight = 99999999\nsamples_per_pixel = 1\nmax_depth = 1\n",
    "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 4294967295\nmax_depth = 4294967295\n"
    "[[spheres]]\ncenter = [0, 0, -1]\nradius = 1e39\nmaterial = \"x\"\n",
    "a = [" * 10_000,
    "[image]\nwidth = 8\n" + "\u202e\x1b[2J" * 100,
    "[materials.m]\ntype = \"lambertian\"\nalbedo = { texture = \"../../../../etc/passwd\" }\n",
    "\x00\xff" * 1000,
]


@pytest.mark.parametrize("text", HOSTILE_TEXTS)
def test_hostile_scene_text_raises_and_the_interpreter_goes_on(text):
    with pytest.raises((tessera.TesseraError, ValueError, OSError)):
        tessera.render(text, width=8, spp=1)
    assert tessera.render("scenes/cover.toml", width=8, spp=1).width == 8


def test_what_a_stranger_wrote_reaches_an_exception_escaped(tmp_path):
    # A scene's unknown key is quoted in the message, which Python prints to the terminal
    # as it is: once the escape sequence and the override themselves.
    hostile = "\u202e\x1b[2J\x1b]0;title\x07\n"
    scene = tmp_path / "hostile.toml"
    # As TOML's escapes, since a raw control character is no TOML.
    scene.write_text('"\\u202E\\u001B[2J\\u001B]0;title\\u0007\\n" = 1\n')
    for given in (scene, {hostile: 1}):
        with pytest.raises(tessera.SceneError) as e:
            tessera.render(given)
        message = str(e.value)
        assert not any(c in message for c in "\u202e\x1b\x07\n"), repr(message)
        assert "\\u{1b}[2J" in message and "\\u{202e}" in message, message


def test_a_simd_path_or_workload_s_name_reaches_an_exception_escaped():
    # The name of a SIMD path or a workload is quoted in the message: once as it was given,
    # escape sequences, bidirectional overrides and all, however long.
    hostile = "x\x1b[2J\u202e" + "a" * 10_000
    calls = [
        lambda: tessera.render("scenes/cover.toml", width=4, spp=1, simd=hostile),
        lambda: tessera.reproduce("none.png", simd=hostile),
        lambda: tessera.bench(hostile, repeat=1, warmup=0),
    ]
    for call in calls:
        with pytest.raises(ValueError) as e:
            call()
        message = str(e.value)
        assert not any(c in message for c in "\u202e\x1b"), repr(message[:100])
        assert "x\\u{1b}[2J\\u{202e}aaa" in message and len(message) < 5000, message[:100]


def test_a_message_quoting_a_long_key_keeps_its_start_and_end(tmp_path):
    # A key of 1 MiB is quoted twice (the field and the unknown key): a message of 2 MB once.
    key = "k" * (1 << 20)
    scene = tmp_path / "long.toml"
    scene.write_text(f"[image]\n{key} = 1\n")
    for given in (scene, {"image": {key: 1}}):
        with pytest.raises(tessera.SceneError) as e:
            tessera.render(given)
        message = str(e.value)
        assert len(message) < 5000, len(message)
        assert "field `image.kkkk" in message and "characters left out) … kkkk" in message


def test_a_panic_is_an_exception_and_the_interpreter_survives():
    with pytest.raises(tessera.TesseraError, match="internal error .* a panic on purpose"):
        tessera._native._panic_for_tests()
    assert tessera.render("scenes/cover.toml", width=8, spp=1).width == 8


def test_a_crash_would_show_here():
    # Each hostile case again, in a fresh interpreter: it must end by raising, not by a
    # signal (an abort or a segmentation fault would be a negative return code).
    code = textwrap.dedent(
        f"""
        import tessera
        texts = {HOSTILE_TEXTS!r}
        for t in texts:
            try:
                tessera.render(t, width=8, spp=1)
            except (tessera.TesseraError, ValueError, OSError):
                pass
        try:
            tessera._native._panic_for_tests()
        except tessera.TesseraError:
            pass
        print("survived")
        """
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert done.stdout.strip() == "survived"


# A name no file can take (`x.png/`, 256 bytes) once failed only at the rename, a hidden
# temporary file of the image left in the directory at each try.
@pytest.mark.parametrize("name", ["out.png/", "out.png/.", "a" * 252 + ".png"])
def test_a_save_to_a_name_no_file_can_take_leaves_nothing(name, tmp_path):
    image = tessera.render("scenes/cover.toml", width=8, spp=1)
    with pytest.raises(OSError):
        image.save(f"{tmp_path}/{name}")
    assert os.listdir(tmp_path) == []


# A save into a directory that does not exist names the directory, not the random name of
# the temporary file that was never made there (`at path "…/.out.png.Ab12Cd.tmp"`).
def test_a_save_into_a_missing_directory_names_the_directory(tmp_path):
    image = tessera.render("scenes/cover.toml", width=8, spp=1)
    missing = tmp_path / "gone"
    with pytest.raises(FileNotFoundError) as e:
        image.save(missing / "out.png")
    said = str(e.value)
    assert f"could not create a file in {missing}: " in said, said
    assert ".tmp" not in said and ".out.png" not in said, said


# A scene of 16384x16384 pixels (a few lines of text) claims 6 GiB for its sums: under a
# memory limit the allocation failed and ended the interpreter (abort, a negative return
# code). It is a MemoryError, and the interpreter goes on to render.
CLAIMS_MEMORY = textwrap.dedent(
    """
    import resource, tessera
    scene = {"image": {"width": 16384, "height": 16384, "samples_per_pixel": 1, "max_depth": 2},
             "camera": {"lookfrom": [0.0, 0.0, 1.0], "lookat": [0.0, 0.0, 0.0], "vfov_deg": 40.0}}
    limit = 2 << 30
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    try:
        tessera.render(scene, threads=1)
        print("rendered")
    except MemoryError as e:
        print("MemoryError:", e)
    print(tessera.render("scenes/cover.toml", width=8, spp=1, threads=1).width)
    """
)


def test_a_scene_too_large_for_memory_is_a_memory_error():
    done = subprocess.run([sys.executable, "-c", CLAIMS_MEMORY], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    said, rendered = done.stdout.splitlines()
    assert said.startswith("MemoryError: the image's 16384x16384 pixels need 6442450944 bytes"), said
    assert rendered == "8"


# Each pass's image given to `on_pass` is a copy of the render's sums: of 2048x2048 pixels,
# 100663296 bytes, whose allocation, failed under a memory limit, ended the interpreter
# (abort). It is a MemoryError, and the interpreter goes on to render.
PASS_CLAIMS_MEMORY = textwrap.dedent(
    """
    import resource, tessera
    def scene(size):
        return {"image": {"width": size, "height": size, "samples_per_pixel": 4, "max_depth": 1},
                "camera": {"lookfrom": [0.0, 0.0, 1.0], "lookat": [0.0, 0.0, 0.0], "vfov_deg": 40.0}}
    def vm_size():
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    # Every thread and arena the render below takes, at a size that needs no memory to speak of.
    tessera.render(scene(64), threads=1, on_pass=lambda image: None)
    sums = 2048 * 2048 * 24
    limit = vm_size() + sums + sums // 2
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    try:
        tessera.render(scene(2048), threads=1, on_pass=lambda image: None)
        print("rendered")
    except MemoryError as e:
        print("MemoryError:", e)
    print(tessera.render(scene(64), threads=1).width)
    """
)


def test_a_pass_image_too_large_for_memory_is_a_memory_error():
    done = subprocess.run([sys.executable, "-c", PASS_CLAIMS_MEMORY], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    said, rendered = done.stdout.splitlines()
    assert said.startswith(
        "MemoryError: the image of pass 1 (2048x2048 pixels) needs 100663296 bytes"
    ), said
    assert rendered == "64"


# A save to a pipe (FIFO) of this user's writes the image into it, for its reader; with no
# reader, the save's open waited in the kernel, where Ctrl-C does not reach: the interpreter
# hung until killed. It waits for a reader where Ctrl-C stops it, and a reader gets the image.
SAVED_TO_A_PIPE = textwrap.dedent(
    """
    import os, signal, sys, threading, tessera
    pipe = os.path.join(sys.argv[1], "out.png")
    os.mkfifo(pipe)
    image = tessera.render("scenes/cover.toml", width=8, spp=1)
    threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
    try:
        image.save(pipe)
        print("saved with no reader")
    except KeyboardInterrupt:
        print("interrupted")
    read = []
    def reader():
        with open(pipe, "rb") as f:
            read.append(f.read())
    thread = threading.Thread(target=reader)
    thread.start()
    image.save(pipe)
    thread.join()
    print(read == [image.png()])
    """
)


def test_a_save_to_a_pipe_waits_for_its_reader_where_ctrl_c_stops_it(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", SAVED_TO_A_PIPE, str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=as_at_a_terminal,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["interrupted", "True"], done.stdout


# A path with a NUL is a bad argument, as Python's own `open` says: `save` and `reproduce`
# raised an OSError, "could not create a file in DIR: file name contained an unexpected NUL
# byte", as if the directory were at fault.
def test_a_path_with_a_nul_is_a_value_error(tmp_path):
    image = tessera.render("scenes/cover.toml", width=8, spp=1)
    for path in (f"{tmp_path}/a\0b.png", os.fsencode(f"{tmp_path}/a\0b.png")):
        with pytest.raises(ValueError, match=r"a\\x00b.png: a path cannot hold a NUL character"):
            image.save(path)
        with pytest.raises(ValueError, match="a path cannot hold a NUL character"):
            tessera.reproduce(path)
    image.save(tmp_path / "ok.png")
    with pytest.raises(ValueError, match="a path cannot hold a NUL character"):
        tessera.reproduce(tmp_path / "ok.png", textures=f"{tmp_path}/t\0")
    with pytest.raises(ValueError, match="a path cannot hold a NUL character"):
        tessera.results(f"{tmp_path}/r\0.db")
    assert os.listdir(tmp_path) == ["ok.png"]
