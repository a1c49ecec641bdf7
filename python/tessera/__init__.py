"""tessera from Python: the deterministic path tracer of *Ray Tracing in One Weekend* and
*The Next Week*, rendering into NumPy arrays with the same bytes as the command line.

    >>> import tessera
    >>> image = tessera.render("scenes/cover.toml", width=300, spp=16)
    >>> image.srgb8.shape            # the PNG's pixels, height x width x RGB
    (200, 300, 3)
    >>> image.save("cover.png")      # the file `tessera render` writes, recipe included

The same scene, settings and seed give the same pixels whatever the thread count or SIMD
path. Rendering releases the interpreter's lock; Ctrl-C stops a render within a tenth of a
second and raises KeyboardInterrupt.
"""

from __future__ import annotations

import json
import numbers
import operator
import os
from typing import Any, Callable, Dict, List, Mapping, NoReturn, Optional, Union

import numpy as np

from . import _native
from ._native import SceneError, TesseraError

__all__ = [
    "Image",
    "SceneError",
    "TesseraError",
    "render",
    "reproduce",
    "bench",
    "results",
    "results_frame",
    "simd_paths",
    "build",
]

__version__ = "0.1.0"

#: What `render` takes as a scene: a scene file's path, a scene file's text, or a dict of
#: its keys (as `docs/scene-format.md` gives them).
SceneLike = Union[str, "os.PathLike[str]", Mapping[str, Any]]

_U32_MAX = 2**32 - 1
_U64_MAX = 2**64 - 1


class Image:
    """A rendered image.

    ``linear`` and ``srgb8`` are read-only NumPy arrays, height x width x 3 (copy one to
    change it). ``save(path)`` writes the file `tessera render` writes for the same scene
    and settings; a notebook shows the image itself.
    """

    __slots__ = ("_native", "_linear", "_srgb8")

    def __init__(self, native: "_native.NativeImage") -> None:
        self._native = native
        self._linear: Optional[np.ndarray] = None
        self._srgb8: Optional[np.ndarray] = None

    @property
    def width(self) -> int:
        return self._native.width

    @property
    def height(self) -> int:
        return self._native.height

    @property
    def samples_per_pixel(self) -> int:
        """The samples each pixel holds (a pass's count, for an image given to ``on_pass``)."""
        return self._native.samples_per_pixel

    @property
    def max_depth(self) -> int:
        return self._native.max_depth

    @property
    def seed(self) -> int:
        return self._native.seed

    @property
    def sums(self) -> str:
        """The hash of the exact sums (``xxh3-128:…``), as recipes and benchmarks write it."""
        return self._native.sums

    @property
    def mean_radiance(self) -> float:
        """The mean linear radiance over every pixel and channel."""
        return self._native.mean_radiance

    @property
    def recipe(self) -> Dict[str, Any]:
        """The recipe the image is saved with: the scene's text, the settings, the build."""
        return json.loads(self._native.recipe)

    @property
    def stats(self) -> Optional[Dict[str, Any]]:
        """Samples, rays, seconds, threads and SIMD path of the render; None for a pass."""
        return self._native.stats()

    @property
    def linear(self) -> np.ndarray:
        """Linear radiance, float32, height x width x 3: each pixel's exact sums' mean."""
        if self._linear is None:
            flat = np.frombuffer(self._native.linear_bytes(), dtype=np.float32)
            self._linear = flat.reshape(self.height, self.width, 3)
        return self._linear

    @property
    def srgb8(self) -> np.ndarray:
        """The PNG's pixels, uint8, height x width x 3 (the scene's gamma applied)."""
        if self._srgb8 is None:
            flat = np.frombuffer(self._native.srgb8_bytes(), dtype=np.uint8)
            self._srgb8 = flat.reshape(self.height, self.width, 3)
        return self._srgb8

    def png(self) -> bytes:
        """The PNG file's bytes, recipe included: what ``save("x.png")`` writes."""
        return self._native.encode_as("png")

    def save(self, path: Union[str, "os.PathLike[str]"]) -> None:
        """Writes the image to ``path``, as PNG, EXR or PPM by its extension, whole or not
        at all, with its recipe (PNG and EXR): byte for byte the file `tessera render`
        writes for the same scene and settings."""
        self._native.save(_fspath(path))

    def _repr_png_(self) -> bytes:
        return self.png()

    def __repr__(self) -> str:
        return (
            f"<tessera.Image {self.width}x{self.height}, {self.samples_per_pixel} spp, "
            f"{self.sums}>"
        )


def _whole(name: str, value: Any, low: int, high: int) -> Optional[int]:
    """``value`` as an int in ``low..=high``, or None; a ValueError says the range."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be a whole number from {low} to {high}, not {value!r}")
    n = operator.index(value)
    if not low <= n <= high:
        raise ValueError(f"{name} must be a whole number from {low} to {high}, got {n}")
    return n


def _json_value(value: Any) -> Any:
    """A NumPy scalar or array in a scene dict, as JSON takes it."""
    if isinstance(value, np.generic):
        return _plain_scalar(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "f" and value.dtype.itemsize > 8:
            # Long doubles, which stay NumPy's in a list: as the float64 a scene file holds.
            value = value.astype(np.float64)
        return value.tolist()
    _not_a_value(value)


def _plain_scalar(value: np.generic) -> Any:
    """A NumPy number, boolean or string as the Python one it holds. ``item()`` leaves a
    long double NumPy's, which JSON handed back to be made plain until a RecursionError: it
    is the float64 a scene file holds (a complex one is none of a scene's values). A date or
    a time span is none either, as in an array: ``item()`` of one in nanoseconds is an
    ``int``, and ``np.datetime64(8, "ns")`` was taken as the number 8."""
    if value.dtype.kind not in "biufU":
        _not_a_value(value)
    item = value.item()
    if isinstance(item, np.floating):
        return float(item)
    if isinstance(item, np.generic):
        _not_a_value(item)
    return item


def _not_a_value(value: Any) -> NoReturn:
    raise ValueError(
        f"a scene dict holds numbers, strings, booleans, lists and dicts; "
        f"{type(value).__name__} is none of them"
    )


#: The most values a scene dict may hold, counted as JSON would write them out (a list or
#: dict held twice, twice): a scene file's bound (`MAX_SCENE_VALUES`, src/scene/values.rs).
_MAX_SCENE_VALUES = 1 << 20
#: The most characters its keys and strings may hold, so counted: a scene file's 64 MiB.
_MAX_SCENE_CHARS = 64 << 20


#: The most dicts and lists a scene dict may nest, itself and a NumPy array's dimensions
#: included: more than any scene needs, fewer than a scene file's parser takes (about 80).
_MAX_SCENE_DEPTH = 64

#: The whole numbers a scene file holds: TOML's, 64-bit signed.
_SCENE_INT_RANGE = (-(1 << 63), (1 << 63) - 1)


def _checked_copy(scene: Mapping) -> Dict[str, Any]:
    """A copy of ``scene`` of plain dicts, lists, strings and numbers, which is what is
    written out as JSON: so what is written is what was checked, whatever the objects it
    was made of say of themselves (a `str` whose `__len__` says 0, an `int` whose `__int__`
    says 1, a dict whose `items()` changes between calls). Refuses a dict,
    at any depth, with a key that is not a string (JSON would turn `1` into `"1"` without a
    word), a whole number beyond a scene file's (named by its keys, not by a place in the
    JSON the user never wrote), one that holds itself, and one larger, written out, than a
    scene file may be: a list held many times over is as many lists in the JSON, and a walk
    without bounds never ends on a dict that holds itself (a YAML anchor and its alias)."""
    values = chars = 0
    copy: Dict[str, Any] = {}
    # The dicts and lists to walk, with where they are and the plain copy to fill, each
    # followed by None once its items are walked, to leave it; those being walked, by id.
    pending: list = [(scene, None, copy)]
    inside: dict = {}
    while pending:
        entry = pending.pop()
        if entry is None:
            inside.popitem()
            continue
        value, where, into = entry
        if id(value) in inside:
            raise ValueError("scene: a dict or list holds itself")
        inside[id(value)] = None
        pending.append(None)
        items = value.items() if isinstance(value, Mapping) else enumerate(value)
        for key, item in items:
            if isinstance(key, str):
                chars += _counted(str.__len__(key), chars)
                key = str.__str__(key)
            elif isinstance(value, Mapping):
                raise ValueError(f"scene: a dict's keys must be strings, not {key!r}")
            if isinstance(item, np.generic):
                # A NumPy number, boolean or string, as the Python one it holds.
                item = _plain_scalar(item)
            if isinstance(item, str):
                # Its length counted before a string of another type is copied as a `str`.
                chars += _counted(str.__len__(item), chars)
                item = str.__str__(item)
            elif isinstance(item, np.ndarray):
                # Written out as nested lists of its elements, each list and element a
                # value: counted before it is, as its shape may claim far more than it holds
                # (`np.broadcast_to` of one number to 2^26 took 15 s and 3 GB to write out,
                # then to be refused; an empty array of 10^7 x 0, 6.7 s and 750 MB of empty
                # lists, then to be refused by the scene's parser).
                item = np.asarray(item)
                _within_depth(len(inside) + item.ndim, where, value, key)
                values += _array_values(item.shape) - 1
                chars += _array_chars(item, _place(where, value, key), values)
            elif isinstance(item, (Mapping, list, tuple)):
                _within_depth(len(inside) + 1, where, value, key)
                plain: Any = {} if isinstance(item, Mapping) else []
                pending.append((item, _place(where, value, key), plain))
                item = plain
            elif isinstance(item, bool):
                pass
            elif isinstance(item, int):
                item = int.__int__(item)
                low, high = _SCENE_INT_RANGE
                if not low <= item <= high:
                    raise ValueError(
                        f"scene: {_shown(_place(where, value, key))} is {item}, beyond "
                        f"the whole numbers a scene file holds ({low} to {high})"
                    )
            elif isinstance(item, float):
                item = float.__float__(item)
            if isinstance(into, dict):
                into[key] = item
            else:
                into.append(item)
            values += 1
            # Counted as each item is copied: a dict whose `items()` (or a list whose
            # `__iter__`) never ends was once copied until memory ran out.
            if values > _MAX_SCENE_VALUES or chars > _MAX_SCENE_CHARS:
                _too_large()
    return copy


def _array_values(shape: "tuple[int, ...]") -> int:
    """The values a NumPy array of ``shape`` is written out as: its elements and the lists
    that hold them, the outermost one not counted (``(2, 3)``: 2 lists of 3, 8 values; an
    empty ``(n, 0)``, n empty lists)."""
    values, lists = 0, 1
    for n in shape:
        lists *= n
        values += lists
        if values > _MAX_SCENE_VALUES:
            break
    return values


def _within_depth(depth: int, where: Any, value: Any, key: Any) -> None:
    """Refuses item `key` of `value` (at `where`) where it nests dicts and lists `depth`
    deep, more than a scene dict may: deeper, a dict was refused four ways as its depth
    grew, by places in the TOML or JSON the user never wrote and, past a thousand, by a
    RecursionError of JSON's."""
    if depth > _MAX_SCENE_DEPTH:
        raise ValueError(
            f"scene: {_shown(_place(where, value, key))} nests dicts and lists {depth} deep, "
            f"more than the {_MAX_SCENE_DEPTH} a scene dict may"
        )


def _counted(n: int, chars: int) -> int:
    """``n`` characters more, refused at once where they bring ``chars`` past the bound."""
    if chars + n > _MAX_SCENE_CHARS:
        _too_large()
    return n


def _too_large() -> None:
    raise ValueError(
        f"scene: more than {_MAX_SCENE_VALUES} values or {_MAX_SCENE_CHARS >> 20} MiB "
        "of text written out, more than a scene file may hold"
    )


def _array_chars(array: np.ndarray, where: Any, values: int) -> int:
    """Checks a NumPy array in a scene dict, whose elements bring the values counted to
    `values`: within the bound on values (before any element is read), of numbers, booleans
    or strings (an array of objects would write out what no check here saw), its whole
    numbers within a scene file's; the characters its strings hold."""
    if values > _MAX_SCENE_VALUES:
        raise ValueError(
            f"scene: {_shown(where)} is a NumPy array of shape {array.shape}, written out as "
            f"more than the {_MAX_SCENE_VALUES} values (elements and lists) a scene file may hold"
        )
    if array.dtype.kind not in "biufU":
        raise ValueError(
            f"scene: {_shown(where)} is a NumPy array of {array.dtype}; a scene dict holds arrays "
            "of numbers, booleans or strings"
        )
    if array.dtype.kind in "iu" and array.size:
        low, high = _SCENE_INT_RANGE
        least, most = int(array.min()), int(array.max())
        if least < low or most > high:
            beyond = least if least < low else most
            raise ValueError(
                f"scene: {_shown(where)} holds {beyond}, beyond the whole numbers a scene file "
                f"holds ({low} to {high})"
            )
    return array.size * (array.dtype.itemsize // 4) if array.dtype.kind == "U" else 0


def _place(where: Any, value: Any, key: Any) -> Any:
    """The place of item `key` of `value`, which is at `where` (a place `_place` gave, or
    None for the dict itself), as the links that make it: written out by `_shown` only for a
    message. Written out for every dict walked, the places of 4,000 dicts in a list under a
    key of a million characters once took 4 GB."""
    return (where, isinstance(value, Mapping), key)


def _shown(place: Any) -> str:
    """A place `_place` gave, written out for a message: `image.width`, `spheres[2].center`,
    its keys escaped (`_escaped`: a dict may come from a stranger's JSON or YAML, and its
    keys once reached the terminal with their escape sequences) and of at most
    `_MAX_SHOWN` characters, its start and end kept."""
    parts = []
    while place is not None:
        place, in_dict, key = place
        parts.append(f".{_escaped(key)}" if in_dict else f"[{key}]")
    shown = "".join(reversed(parts)).removeprefix(".")
    if len(shown) > _MAX_SHOWN:
        half = _MAX_SHOWN // 2
        shown = f"{shown[:half]}…{shown[-half:]}"
    return shown


#: The most characters of a place `_shown` writes out.
_MAX_SHOWN = 400


def _scene_input(scene: SceneLike) -> "tuple[str, str]":
    """What the native side is handed: ("file", path), ("toml", text) or ("json", dict)."""
    if isinstance(scene, Mapping):
        plain = _checked_copy(scene)
        try:
            text = json.dumps(plain, allow_nan=False, default=_json_value)
        except ValueError as e:
            raise ValueError(f"scene: {e}") from None
        return ("json", text)
    if isinstance(scene, os.PathLike):
        return ("file", _existing(_fspath(scene)))
    if isinstance(scene, str):
        # A scene file's text has a key (`=`) or a table (`[`); a path has neither.
        if "\n" in scene or "=" in scene or scene.lstrip().startswith("["):
            return ("toml", scene)
        return ("file", _existing(scene))
    raise TypeError(
        "scene must be a path, a scene file's text or a dict, "
        f"not {type(scene).__name__}"
    )


def _existing(path: str) -> str:
    if "\0" in path:
        raise ValueError("scene: a path cannot hold a NUL character")
    if not os.path.exists(path):
        raise FileNotFoundError(f"{_escaped(path)}: no such scene file")
    return path


def _fspath(path: Union[str, bytes, "os.PathLike[Any]"]) -> str:
    """A path (a ``str``, ``bytes`` or path-like object) as the ``str`` Python's own file
    functions take: the bytes of a name that is not UTF-8 as surrogates, which the native
    side turns back into those bytes. A path given as bytes once raised "'bytes' object is
    not an instance of 'str'", and a scene file's name that is not UTF-8 a
    UnicodeEncodeError. A NUL, which no path holds, is a ValueError, as Python's own file
    functions raise: ``save`` and ``reproduce`` raised an OSError of a file that could not
    be created, naming the directory."""
    text = os.fsdecode(os.fspath(path))
    if "\0" in text:
        raise ValueError(f"{_escaped(text)}: a path cannot hold a NUL character")
    return text


def _escaped(text: Any) -> str:
    """A path or key as a message quotes it: its control, bidirectional and other
    unprintable characters escaped (as ``repr`` escapes them), since a terminal prints a
    message as it is, and a name in a shared directory is anyone's."""
    return repr(str(text))[1:-1]


def render(
    scene: SceneLike,
    *,
    width: Optional[int] = None,
    spp: Optional[int] = None,
    depth: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    simd: Optional[str] = None,
    on_pass: Optional[Callable[[Image], Any]] = None,
) -> Image:
    """Renders ``scene`` and returns the Image.

    scene: a scene file's path (``str`` or ``pathlib.Path``), a scene file's text (a ``str``
        holding ``=`` or a newline), or a dict of the scene file's keys. Image textures of a
        scene given as text or a dict are looked for in the working directory, then in its
        ``scenes/``.
    width, spp, depth, seed: replace the scene's ``width`` (the height follows its aspect
        ratio), ``samples_per_pixel``, ``max_depth`` and ``seed``, as the command line's
        ``--width``, ``--spp``, ``--depth`` and ``--seed`` do.
    threads: worker threads (1 to 4096); None uses one per CPU. The image is the same.
    simd: "portable", "avx2", "avx512" or "auto" (None); the image is the same on each.
    on_pass: called with the Image after each progressive pass (1, 4, 16, … samples per
        pixel, then all of them); the final image is the same as without it. What it
        raises stops the render and is raised here.

    Raises SceneError (with ``file``, ``line``, ``column`` and ``field``) for a scene
    tessera cannot render, ValueError for a bad argument, FileNotFoundError for a missing
    scene file, TesseraError for what else tessera refuses, and KeyboardInterrupt when
    Ctrl-C stops the render (a signal handler runs during it: what it raises stops the
    render and is raised).
    """
    kind, text = _scene_input(scene)
    if simd is not None and not isinstance(simd, str):
        raise ValueError(f"simd must be a SIMD path's name, not {simd!r}")
    if on_pass is not None and not callable(on_pass):
        raise TypeError("on_pass must be callable")
    callback = None if on_pass is None else (lambda native: on_pass(Image(native)))
    native = _native.render(
        kind,
        text,
        width=_whole("width", width, 1, _U32_MAX),
        spp=_whole("spp", spp, 1, _U32_MAX),
        depth=_whole("depth", depth, 1, _U32_MAX),
        seed=_whole("seed", seed, 0, _U64_MAX),
        threads=_whole("threads", threads, 1, 4096),
        simd=simd,
        on_pass=callback,
    )
    return Image(native)


def simd_paths() -> "tuple[List[str], str]":
    """The SIMD paths this CPU runs, slowest first, and the one ``auto`` takes."""
    paths, best = _native.simd_paths()
    return list(paths), best


def build() -> Dict[str, Any]:
    """The build of tessera in this package: version, commit, rustc, target, profile."""
    return json.loads(_native.build())


def reproduce(
    image: Union[str, "os.PathLike[str]"],
    *,
    threads: Optional[int] = None,
    simd: Optional[str] = None,
    textures: Optional[Union[str, "os.PathLike[str]"]] = None,
    any_cost: bool = False,
) -> Dict[str, Any]:
    """Renders again the recipe a PNG or EXR image carries and says whether the image is bit
    for bit what it makes, as `tessera reproduce` does.

    Returns a dict: ``verdict`` ("identical" or "differs"), ``summary``, ``details`` (a
    line per difference), ``sums`` (the recipe's) and ``work`` (what the recipe asks for).
    A recipe asking for more than four book covers' work (as it claims, and again at what
    its paths cost, a few of them traced), or more than 8192x4096 pixels, raises
    TesseraError unless ``any_cost``. Texture files are looked for in ``textures`` first,
    then beside the image, then in ``scenes/``. An image without a recipe, or one tessera
    cannot read, raises TesseraError.
    """
    if simd is not None and not isinstance(simd, str):
        raise ValueError(f"simd must be a SIMD path's name, not {simd!r}")
    return _native.reproduce(
        _fspath(image),
        threads=_whole("threads", threads, 1, 4096),
        simd=simd,
        textures=None if textures is None else _fspath(textures),
        any_cost=bool(any_cost),
    )


def bench(
    workload: str = "quick",
    threads: Optional[int] = None,
    *,
    scaling: bool = False,
    repeat: int = 3,
    warmup: int = 1,
    simd: Optional[str] = None,
) -> Dict[str, Any]:
    """Measures a standard workload as `tessera bench` does and returns the result, a dict
    of the `tessera-bench` JSON schema (docs/benchmark-json.md); it is not recorded in the
    results database (`tessera results import` takes it, saved as JSON).

    workload: "quick", "cover", "cornell" or "next-week".
    threads: of the headline result (default: every CPU). scaling: also measure 1, 2, 4, …
    threads. repeat: measured renders per thread count (the median is reported). warmup:
    renders before measuring. Ctrl-C stops it and raises KeyboardInterrupt.
    """
    if not isinstance(workload, str):
        raise ValueError(f"workload must be a workload's name, not {workload!r}")
    if simd is not None and not isinstance(simd, str):
        raise ValueError(f"simd must be a SIMD path's name, not {simd!r}")
    text = _native.bench(
        workload,
        threads=_whole("threads", threads, 1, 4096),
        scaling=bool(scaling),
        repeat=_whole("repeat", repeat, 1, 1000),
        warmup=_whole("warmup", warmup, 0, 1000),
        simd=simd,
    )
    return json.loads(text)


def results(
    db: Optional[Union[str, "os.PathLike[str]"]] = None,
    *,
    workload: Optional[str] = None,
    machine: Optional[str] = None,
    commit: Optional[str] = None,
    limit: Optional[int] = None,
) -> List[Dict[str, Any]]:
    """The runs a results database holds, newest first, as `tessera results list` shows
    them: a dict per run (``id``, ``started_unix_s``, ``machine_id``, ``cpu_model``,
    ``workload``, ``threads``, ``samples_per_second`` and its min and max, ``validation``,
    ``busy``, …) with its whole result (the JSON schema's dict) under ``result``.

    db: the database's path; None takes $TESSERA_DB, else the default one
    ($XDG_DATA_HOME/tessera/results.db or ~/.local/share/tessera/results.db).
    workload, machine (a machine id's prefix or part of a CPU model), commit (a prefix) and
    limit select runs as `results list`'s flags do.
    """
    if db is None:
        db = os.environ.get("TESSERA_DB") or None
    runs = _native.results(
        None if db is None else _fspath(db),
        workload=workload,
        machine=machine,
        commit=commit,
        limit=_whole("limit", limit, 0, _U32_MAX),
    )
    for run in runs:
        # A database tessera did not write may hold a result that is not JSON, or nested
        # past the interpreter's recursion limit.
        try:
            run["result"] = json.loads(run["result"])
        except (ValueError, RecursionError) as e:
            raise TesseraError(
                f"{'the results database' if db is None else _escaped(_fspath(db))}: "
                f"run {run['id']}: its result "
                f"is not JSON ({type(e).__name__}); "
                "tessera writes none such"
            ) from None
    return runs


def results_frame(db: Optional[Union[str, "os.PathLike[str]"]] = None, **select: Any) -> Any:
    """``results(db, ...)`` as a pandas DataFrame, a row per run (pandas must be installed:
    ``pip install pandas``); ``started`` is the start as a UTC timestamp."""
    try:
        import pandas
    except ImportError:
        raise ImportError(
            "tessera.results_frame needs pandas: pip install pandas "
            "(tessera.results gives the same runs as dicts)"
        ) from None
    frame = pandas.DataFrame(results(db, **select))
    if "started_unix_s" in frame:
        frame.insert(1, "started", pandas.to_datetime(frame["started_unix_s"], unit="s", utc=True))
    return frame
