# Type stubs of tessera._native, the extension module (python/src/lib.rs). The documented
# API is tessera's own (tessera/__init__.py), which checks its arguments and calls these.

from typing import Any, Callable, Dict, List, Optional, Tuple

class TesseraError(Exception): ...

class SceneError(TesseraError):
    file: str
    line: int
    column: int
    field: Optional[str]

class NativeImage:
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def samples_per_pixel(self) -> int: ...
    @property
    def max_depth(self) -> int: ...
    @property
    def seed(self) -> int: ...
    @property
    def gamma(self) -> float: ...
    @property
    def sums(self) -> str: ...
    @property
    def mean_radiance(self) -> float: ...
    @property
    def recipe(self) -> str: ...
    def linear_bytes(self) -> bytes: ...
    def srgb8_bytes(self) -> bytes: ...
    def encode_as(self, format: str) -> bytes: ...
    def save(self, path: str) -> None: ...
    def stats(self) -> Optional[Dict[str, Any]]: ...

def render(
    kind: str,
    scene: str,
    *,
    width: Optional[int] = None,
    spp: Optional[int] = None,
    depth: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    simd: Optional[str] = None,
    on_pass: Optional[Callable[[NativeImage], Any]] = None,
) -> NativeImage: ...
def reproduce(
    image: str,
    *,
    threads: Optional[int] = None,
    simd: Optional[str] = None,
    textures: Optional[str] = None,
    any_cost: bool = False,
) -> Dict[str, Any]: ...
def bench(
    workload: str,
    *,
    threads: Optional[int] = None,
    scaling: bool = False,
    repeat: int = 3,
    warmup: int = 1,
    simd: Optional[str] = None,
) -> str: ...
def results(
    db: Optional[str] = None,
    *,
    workload: Optional[str] = None,
    machine: Optional[str] = None,
    commit: Optional[str] = None,
    limit: Optional[int] = None,
) -> List[Dict[str, Any]]: ...
def simd_paths() -> Tuple[List[str], str]: ...
def build() -> str: ...
def _panic_for_tests() -> None: ...
