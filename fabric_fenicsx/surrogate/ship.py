"""Table tiles shipped with the package: a read-only seed of the surrogate's tile cache.

The first run of a scene on a fresh machine would spend most of its time solving the table
tiles the scene visits (the demo visits the whole default table). The folder ``shipped/``
beside this module holds those tiles for the table the demo scenes use, in the cache's own
layout and format: ``shipped/surrogate-<key>/<tile>.npz``, each file with its key, its tile's
name and a checksum covering both and the values (zip-compressed), and ``shipped/tables.json``,
the list of the shipped tables (fabric preset, table settings, key) and of their tiles.

A :class:`~fabric_fenicsx.surrogate.table.Surrogate` whose own cache lacks a tile reads it here
before solving it (:class:`ShippedTiles`; the surrogate's ``shipped`` argument) and copies it
into its cache when that can be written, so that the cache then holds every tile a run used, as
if it had solved them. A shipped tile is checked like a cached one
(:func:`~fabric_fenicsx.surrogate.tiles.load_tile`): one that fails (another key, another
tile's file, a changed byte) is solved instead, with a :class:`ShippedTileWarning`. A changed
fabric or table setting gives another key, and the shipped tiles are then simply not found; a
change of the unit cell's numbers that keeps the key (``tiles.FORMAT_VERSION`` should mark it)
is caught by the test that solves shipped tiles afresh (tests/surrogate/test_shipped.py).

:func:`ship` (``fabric-fenicsx surrogate ship``) rewrites the folder: it solves every listed
tile with the code as it is now, adding the tiles a cache folder holds (``--add-from DIR``: the
cache of scene runs started with ``FABRIC_FENICSX_CACHE=DIR`` empty; that is how the list was
made).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
import uuid
import warnings
from pathlib import Path

import numpy as np

from fabric_fenicsx.atomic import write_atomic
from fabric_fenicsx.surrogate.tiles import load_tile, save_tile

SHIPPED_DIR = Path(__file__).resolve().with_name("shipped")
"""The shipped tiles (package data)."""
MANIFEST = "tables.json"
"""The list of shipped tables and tiles, in :data:`SHIPPED_DIR`."""
LAYERS = ("intact", "damaged")
TABLE_SETTINGS = {"resolution", "r_nodes", "order", "E_min", "n_elements", "tile"}
"""The :class:`~fabric_fenicsx.surrogate.table.Surrogate` arguments a listed table may set."""
_TILE_FILE = re.compile(r"^(intact|damaged)_(\d+)_(\d+)\.npz$")


class ShippedTileWarning(UserWarning):
    """A shipped tile failed its check (key, tile name or checksum) and is solved instead."""


class ShippedTiles:
    """The shipped tiles of one table (cache key ``key``) under ``root`` (default
    :data:`SHIPPED_DIR`; any folder of the same layout works as a seed). ``used`` counts the
    tiles read, ``rejected`` the ones that failed their check."""

    def __init__(self, key: str, root: str | Path | None = None):
        self.key = key
        self.folder = Path(root if root is not None else SHIPPED_DIR) / f"surrogate-{key}"
        self.present = self.folder.is_dir()
        self.used = self.rejected = 0

    def load(self, tile: str, shape: tuple) -> np.ndarray | None:
        """The values of tile ``tile`` if it is shipped and passes its check, else None (a
        :class:`ShippedTileWarning` when a shipped file fails it)."""
        if not self.present:
            return None
        path = self.folder / f"{tile}.npz"
        if not path.is_file():
            return None
        values = load_tile(path, self.key, shape, tile)
        if values is None:
            self.rejected += 1
            warnings.warn(f"shipped surrogate tile {path} fails its check (key {self.key}, tile "
                          f"name, shape or checksum): solving it instead; `fabric-fenicsx "
                          f"surrogate ship` rewrites the shipped tiles", ShippedTileWarning,
                          stacklevel=3)
            return None
        self.used += 1
        return values


# ---------------------------------------------------------------------------- the list
def read_manifest(root: str | Path | None = None) -> dict:
    """``tables.json`` of ``root`` (default :data:`SHIPPED_DIR`): ``{"tables": [{"fabric",
    "bending", "settings", "key", "visited_by", "tiles": {"intact": [...], "damaged": [...]}}]}``
    (tile names without their layer, e.g. ``"2_3"``); ValueError naming the file if it is
    missing or malformed."""
    path = Path(root if root is not None else SHIPPED_DIR) / MANIFEST
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        tables = data["tables"]
        for t in tables:
            settings = t.get("settings", {})
            if not (isinstance(t["fabric"], str) and isinstance(settings, dict)
                    and set(settings) <= TABLE_SETTINGS and set(t["tiles"]) <= set(LAYERS)):
                raise ValueError(f"a table entry is malformed: {t!r}")
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{path}: not a list of shipped surrogate tables ({err})") from None
    return data


def table_fabric(entry: dict):
    """The fabric of a manifest entry: a built-in preset by name (``zylon_as`` with its
    ``bending``), so that a changed preset is shipped as it is now."""
    from fabric_fenicsx.material.fabric import zylon_as

    presets = {"zylon_as": lambda e: zylon_as(e.get("bending", "max"))}
    if entry["fabric"] not in presets:
        raise ValueError(f"shipped table fabric {entry['fabric']!r} is not a preset; "
                         f"valid: {sorted(presets)}")
    return presets[entry["fabric"]](entry)


def cached_tiles(cache_root: str | Path, key: str) -> dict[str, set[tuple[int, int]]]:
    """The tiles of table ``key`` that the cache folder ``cache_root`` holds (by file name),
    per layer: what runs that started from this empty cache visited."""
    found = {layer: set() for layer in LAYERS}
    folder = Path(cache_root) / f"surrogate-{key}"
    for path in (sorted(folder.iterdir()) if folder.is_dir() else ()):
        m = _TILE_FILE.match(path.name)
        if m:
            found[m[1]].add((int(m[2]), int(m[3])))
    return found


def _names(tiles) -> list[str]:
    return [f"{a}_{b}" for a, b in sorted(tiles)]


def _parse(names, where: str) -> set[tuple[int, int]]:
    out = set()
    for name in names:
        parts = name.split("_")
        if len(parts) != 2 or not all(p.isdigit() for p in parts):
            raise ValueError(f"{where}: tile {name!r} is not 'a_b'")
        out.add((int(parts[0]), int(parts[1])))
    return out


# ---------------------------------------------------------------------------- rewriting
def ship(root: str | Path | None = None, add_from=(), workers: int | None = None,
         progress: bool = True, say=print) -> list[dict]:
    """Rewrite the shipped tiles under ``root`` (default :data:`SHIPPED_DIR`): for each table
    of its ``tables.json``, solve the listed tiles and those the cache folders ``add_from``
    hold for the table's current key, with the code as it is now (in a temporary cache, on
    ``workers`` processes), write them compressed into ``surrogate-<key>/`` (a new folder
    renamed into place), remove the folders of keys no longer listed and rewrite the list
    with the keys and tiles. Returns per table its key, tile counts and bytes on disk."""
    from fabric_fenicsx.surrogate.table import Surrogate

    root = Path(root if root is not None else SHIPPED_DIR)
    manifest = read_manifest(root)
    report = []
    with tempfile.TemporaryDirectory(prefix="ship-", dir=root) as scratch:
        for entry in manifest["tables"]:
            fabric = table_fabric(entry)
            sur = Surrogate(fabric, **entry.get("settings", {}), cache_dir=Path(scratch),
                            shipped=False, workers=workers, progress=progress)
            tiles = {layer: _parse(entry["tiles"].get(layer, ()), str(root / MANIFEST))
                     for layer in LAYERS}
            for cache in add_from:
                for layer, found in cached_tiles(cache, sur.key).items():
                    tiles[layer] |= found
            tiles["intact"] |= tiles["damaged"]  # a damaged tile's r = 1 is the intact one
            for layer in LAYERS:
                outside = {t for t in tiles[layer] if max(t) >= sur.n_tiles}
                if outside:
                    say(f"ship: {entry['fabric']}: dropping {layer} tiles {_names(outside)} "
                        f"outside the table's {sur.n_tiles} x {sur.n_tiles} tiles")
                tiles[layer] -= outside
                sur.ensure_tiles(layer, sorted(tiles[layer]))
            new = root / f".surrogate-{sur.key}.new-{uuid.uuid4().hex[:8]}"
            try:
                size = _write_tiles(sur, tiles, new)
                final = root / f"surrogate-{sur.key}"
                if final.exists():
                    shutil.rmtree(final)
                os.replace(new, final)
            finally:
                shutil.rmtree(new, ignore_errors=True)
            entry.update(key=sur.key, tiles={layer: _names(tiles[layer]) for layer in LAYERS})
            row = {"fabric": entry["fabric"], "key": sur.key, "bytes": size,
                   **{layer: len(tiles[layer]) for layer in LAYERS}}
            say(f"ship: {row['fabric']} table {sur.key}: {row['intact']} intact and "
                f"{row['damaged']} damaged tiles, {size / 1e6:.2f} MB")
            report.append(row)
    keep = {f"surrogate-{e['key']}" for e in manifest["tables"]}
    for old in root.glob("surrogate-*"):
        if old.is_dir() and old.name not in keep:
            shutil.rmtree(old)
    write_atomic(root / MANIFEST, json.dumps(manifest, indent=1) + "\n")
    return report


def _write_tiles(sur, tiles: dict, folder: Path) -> int:
    """Copy the solved ``tiles`` (per layer) of ``sur``'s cache into ``folder``, compressed;
    returns their bytes on disk."""
    size = 0
    for layer in LAYERS:
        for a, b in sorted(tiles[layer]):
            name = sur._tile_name(layer, a, b)
            src = sur._tile_path(layer, a, b)
            with np.load(src, allow_pickle=False) as f:
                values = f["values"]
            if load_tile(src, sur.key, values.shape, name) is None:
                raise RuntimeError(f"ship: the tile {name} just solved fails its check")
            save_tile(folder / f"{name}.npz", sur.key, values, name, compress=True)
            size += (folder / f"{name}.npz").stat().st_size
    return size
