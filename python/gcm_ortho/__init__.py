"""gcm-ortho: orthorectification of huge scans on small machines.

The method is the generalized correction matrix of Beloshapkin's thesis on
the digital orthorectification of aerial photographs: per output row a
fractional-linear approximation, plus exact corrections (terrain, lens,
refraction, curvature) at sparse nodes, interpolated between them.

Every function takes its settings as keyword arguments named as the
command line's options, ``_`` for ``-`` (``max_error=0.05``,
``compress="zstd"``, ``memory="512M"``), the keys of a batch manifest.
Runs stream within ``memory`` whatever the input's size, release the GIL,
and stop cleanly on Ctrl-C (``KeyboardInterrupt``, nothing left at the
output path). Errors raise :class:`GcmOrthoError` subclasses carrying the
command's one-line message; doubtful input gives a :class:`GcmOrthoWarning`.

DEMs: :func:`grid` from points, :func:`dem` from a stereo pair.

Windows for Dask: :func:`plan` fixes the output grid once,
:func:`render_window` makes a piece of it (a file, or a NumPy array with its
mask), :func:`assemble` joins pieces into the file a single run writes,
byte for byte. See docs/PYTHON.md.
"""

from __future__ import annotations

import json as _json
import numbers
import os
import tempfile
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Optional, Sequence, Tuple, Union

from . import _native
from .errors import (
    CancelledError,
    GcmOrthoError,
    GcmOrthoWarning,
    GeometryError,
    InputError,
    InputOutputError,
    InternalError,
    LimitError,
    SettingError,
    UnsupportedError,
)

__version__: str = _native.__version__

__all__ = [
    "rectify",
    "mosaic",
    "grid",
    "dem",
    "plan",
    "mosaic_plan",
    "Plan",
    "render_window",
    "Window",
    "assemble",
    "read",
    "GcmOrthoError",
    "InputError",
    "InputOutputError",
    "UnsupportedError",
    "LimitError",
    "SettingError",
    "GeometryError",
    "InternalError",
    "CancelledError",
    "GcmOrthoWarning",
]

PathLike = Union[str, "os.PathLike[str]"]
#: ``progress(done, total, task)``: called from the calling thread at most
#: every ``progress_interval`` seconds, and once at the end.
ProgressCallback = Callable[[int, int, str], Any]


def _value(v: Any) -> Any:
    """A keyword argument's value as the key table takes it: paths as
    text, tuples and NumPy arrays as lists, NumPy scalars as numbers."""
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    if isinstance(v, (tuple, list)):
        return [_value(x) for x in v]
    if type(v).__module__ == "numpy":
        return _value(v.tolist())
    return v


def _keys(**keys: Any) -> str:
    out = {}
    for k, v in keys.items():
        if v is None:
            continue
        out[k] = _value(v)
        try:
            _json.dumps(out[k])
        except (TypeError, ValueError):
            raise SettingError(f"{k}: {v!r} is not a value a setting takes (a number, text, a path, a list of them)") from None
    return _json.dumps(out)


def _write_report(path: PathLike, report: dict) -> None:
    """The report as ``--json`` writes it: a temporary file renamed."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".", suffix=".json.tmp")
    try:
        with os.fdopen(fd, "w") as f:
            _json.dump(report, f, indent=2)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def _run(native: Callable[..., str], keys: str, progress: Optional[ProgressCallback], interval: float, json: Optional[PathLike]) -> dict:
    """A native run; its report as a dict, also written to ``json``."""
    report = _json.loads(native(keys, progress, interval))
    if json is not None:
        _write_report(json, report)
    return report


def _sensor_keys(camera: Optional[PathLike], dem: Union[PathLike, float, None], options: dict) -> dict:
    keys = dict(options)
    if camera is not None:
        keys["camera"] = camera
    # A number is a constant height (the command line's --height).
    if isinstance(dem, numbers.Real) and not isinstance(dem, bool):
        keys["height"] = float(dem)
    elif dem is not None:
        keys["dem"] = dem
    return keys


def rectify(
    image: PathLike,
    camera: Optional[PathLike] = None,
    dem: Union[PathLike, float, None] = None,
    out: Optional[PathLike] = None,
    *,
    progress: Optional[ProgressCallback] = None,
    progress_interval: float = 0.5,
    json: Optional[PathLike] = None,
    **options: Any,
) -> dict:
    """Orthorectifies ``image`` onto ``dem`` and writes the GeoTIFF ``out``.

    ``camera``: the camera file (or, with ``exterior=``, the lens of a block
    whose poses that file holds); a satellite image takes ``rpc=`` instead
    (its RPC file, or the image itself). ``dem``: a DEM/DSM file, or a
    constant height in metres (an RPC alone: its own height offset).
    ``options``: the command line's options by key (``gsd``, ``bounds``,
    ``crs``, ``max_error``, ``sparsity``, ``resample``, ``compress``,
    ``nodata``, ``occlusion``, ``gcps``, ``window``, ``memory``,
    ``threads``, ``sync``...). ``json``: also write the report there.

    Returns the run's report (the command's ``--json``) as a dict.
    """
    keys = _sensor_keys(camera, dem, options)
    return _run(_native.rectify, _keys(image=image, output=out, **keys), progress, progress_interval, json)


def mosaic(
    manifest: PathLike,
    out: Optional[PathLike] = None,
    *,
    progress: Optional[ProgressCallback] = None,
    progress_interval: float = 0.5,
    **options: Any,
) -> dict:
    """Makes one seamless orthomosaic of the images a batch manifest lists.

    ``options``: the ``mosaic`` command's (``gsd``, ``bounds``, ``crs``,
    ``like``, ``balance``, ``seams``, ``blend``, ``seamlines``,
    ``seamlines_out``, ``plan``, ``plan_out``, ``window``, ``cog``,
    ``occlusion``, ``memory``, ``threads``, ``force``, ``json``). With
    ``plan_out`` and no ``out``: the plan (seams, gains) alone, for pieces
    rendered elsewhere with ``plan=`` and ``window=``.
    """
    text = _native.mosaic(_keys(manifest=manifest, output=out, **options), progress, progress_interval)
    return _json.loads(text)


def grid(
    points: Union[PathLike, Sequence[PathLike]],
    out: PathLike,
    gsd: Union[float, Tuple[float, float]],
    *,
    progress: Optional[ProgressCallback] = None,
    progress_interval: float = 0.5,
    json: Optional[PathLike] = None,
    **options: Any,
) -> dict:
    """A DEM of cell size ``gsd`` from points (CSV/XYZ, LAS, LAZ; one file or
    a list), streamed within ``memory``.

    ``options``: the ``grid`` command's (``crs``, ``points_crs``,
    ``bounds``, ``method`` — ``tin``, ``natural``, ``idw``, ``nearest``,
    ``max``, ``min``, ``mean`` —, ``max_edge``, ``radius``, ``power``,
    ``neighbours``, ``columns``, ``classes`` (the ASPRS classes kept: the
    command's ``--class``), ``returns``, ``blunders``, ``tile``,
    ``compress``, ``overviews``, ``cog``, ``window``, ``shard=(i, n)``,
    ``memory``, ``threads``)."""
    if isinstance(points, (str, os.PathLike)):
        points = [points]
    if "classes" in options:
        options["class"] = options.pop("classes")
    return _run(_native.grid, _keys(points=list(points), output=out, gsd=gsd, **options), progress, progress_interval, json)


def dem(
    left: PathLike,
    right: PathLike,
    out: PathLike,
    gsd: Union[float, Tuple[float, float]],
    *,
    progress: Optional[ProgressCallback] = None,
    progress_interval: float = 0.5,
    json: Optional[PathLike] = None,
    **options: Any,
) -> dict:
    """A DSM of cell size ``gsd`` from a stereo pair: ``left_camera`` and
    ``right_camera`` (frame cameras) or ``left_rpc`` and ``right_rpc``
    (with ``left_rpc_offset``, ``right_rpc_offset``, ``geoid``).

    ``options``: the ``dem`` command's (``crs``, ``heights=(lo, hi)``,
    ``dem_init``, ``matcher`` — ``sgm`` or ``ncc`` —, ``window``,
    ``min_correlation``, ``points``, ``quality``, ``blunders``, ``cog``,
    ``memory``, ``threads``)."""
    return _run(_native.dem, _keys(left=left, right=right, output=out, gsd=gsd, **options), progress, progress_interval, json)


@dataclass(frozen=True)
class Plan:
    """A run's settings with the output grid they make, fixed once.

    Picklable: send it to workers. ``width``/``height`` in pixels,
    ``tile`` the tile side; windows are in tiles (as ``window=`` and
    ``--window`` take them). ``transform`` is GDAL's geotransform.
    """

    options: dict
    width: int
    height: int
    tile: int
    tiles_across: int
    tiles_down: int
    transform: Tuple[float, ...]
    crs: str
    bands: int = field(default=0)
    #: ``rectify`` (one image) or ``mosaic`` (a block, its seams and gains
    #: in the plan file ``options["plan"]``).
    kind: str = "rectify"

    def windows(self, tiles: int = 8) -> Iterator[Tuple[int, int, int, int]]:
        """The grid in windows of ``tiles`` × ``tiles`` tiles (the last
        ones smaller): ``(col, row, width, height)`` in tiles."""
        if tiles < 1:
            raise SettingError("tiles: must be 1 or more")
        for row in range(0, self.tiles_down, tiles):
            for col in range(0, self.tiles_across, tiles):
                yield col, row, min(tiles, self.tiles_across - col), min(tiles, self.tiles_down - row)


def plan(
    image: PathLike,
    camera: Optional[PathLike] = None,
    dem: Union[PathLike, float, None] = None,
    **options: Any,
) -> Plan:
    """The output grid :func:`rectify` makes with these settings, without
    rendering a pixel; the settings are kept to render its windows."""
    keys = _json.loads(_keys(image=image, **_sensor_keys(camera, dem, options)))
    keys.pop("window", None)
    # A placeholder output: the plan writes nothing.
    grid = _json.loads(_native.plan(_json.dumps(dict(keys, output="plan.tif"))))
    grid["transform"] = tuple(grid["transform"])
    return Plan(options=keys, **grid)


def mosaic_plan(manifest: PathLike, plan_out: PathLike, **options: Any) -> Plan:
    """Plans a mosaic once (grid, seams, gains) into the file ``plan_out``,
    for its windows to be rendered anywhere by :func:`render_window` and
    joined by :func:`assemble`. ``options``: as :func:`mosaic`'s; ``cog``
    goes to the pieces (the whole's layout)."""
    layout = {k: options[k] for k in ("cog",) if k in options}
    report = mosaic(manifest, None, plan_out=plan_out, **options)
    tile = report["tile"]
    keys = _json.loads(_keys(manifest=manifest, plan=plan_out, **layout))
    return Plan(
        options=keys,
        width=report["width"],
        height=report["height"],
        tile=tile,
        tiles_across=-(-report["width"] // tile),
        tiles_down=-(-report["height"] // tile),
        transform=(),
        crs=report["crs"],
        kind="mosaic",
    )


@dataclass
class Window:
    """A window of an orthophoto: ``data`` is bands × rows × cols,
    ``mask`` rows × cols (True: the pixel has a value); ``col``/``row``:
    its first pixel in the whole grid."""

    data: "Any"
    mask: "Any"
    col: int
    row: int


def read(path: PathLike) -> Window:
    """An orthophoto (or a piece of one) as a :class:`Window`: its pixels,
    and which have a value (its internal mask, else its alpha band, else
    its nodata value)."""
    import numpy as np

    pixels, width, height, bands, sample, mask, nodata = _native.read_raster(os.fspath(path))
    data = np.frombuffer(pixels, dtype=np.dtype(sample)).reshape(height, width, bands).transpose(2, 0, 1)
    if mask is not None:
        valid = np.frombuffer(mask, dtype=np.uint8).reshape(height, width).astype(bool)
    elif nodata is not None and np.isnan(nodata):
        valid = ~np.isnan(data).all(axis=0)
    elif nodata is not None:
        valid = (data != data.dtype.type(nodata)).any(axis=0)
    else:
        valid = np.ones((height, width), dtype=bool)
    return Window(data=data, mask=valid, col=0, row=0)


def render_window(
    plan: Plan,
    col: int,
    row: int,
    width: int,
    height: int,
    out: Optional[PathLike] = None,
    **options: Any,
) -> Union[Window, dict]:
    """Renders tiles ``col``, ``row`` (``width`` × ``height`` tiles) of
    ``plan``'s grid, pixel for pixel as the single run makes them.

    With ``out``: writes the piece there (for :func:`assemble`) and returns
    its report. Without: returns the window as a :class:`Window` (NumPy
    arrays). ``options``: resources for this piece (``memory``,
    ``threads``)."""
    keys = dict(plan.options, window=[col, row, width, height], **_json.loads(_keys(**options)))
    run = _native.mosaic if plan.kind == "mosaic" else _native.rectify
    if out is not None:
        return _json.loads(run(_json.dumps(dict(keys, output=os.fspath(out)))))
    with tempfile.TemporaryDirectory(prefix="gcm-ortho-window-") as folder:
        piece = os.path.join(folder, "piece.tif")
        run(_json.dumps(dict(keys, output=piece, sync=False)))
        w = read(piece)
    w.col, w.row = col * plan.tile, row * plan.tile
    return w


def assemble(pieces: Sequence[PathLike], out: PathLike, **options: Any) -> None:
    """Joins pieces of one grid (from :func:`render_window` or ``window=``
    runs) into the whole, as a single run would have written it.
    ``options``: ``overviews``, ``overview_resampling``, ``cog``, ``level``,
    ``overview_level``, ``quality``, ``compress``."""
    _native.assemble([os.fspath(p) for p in pieces], os.fspath(out), _keys(**options))

