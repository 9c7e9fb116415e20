"""The table tiles shipped with the package (``fabric_fenicsx/surrogate/shipped/``): present for the
demo scenes' table, read instead of solved when the cache lacks them, rejected with a warning
when they fail their check, equal to what the unit cell gives now; and ``surrogate ship``.
"""

import json
import shutil
import warnings
import zipfile

import numpy as np
import pytest

from fabric_fenicsx.cli import main
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.surrogate import ship as ship_module
from fabric_fenicsx.surrogate import tiles
from fabric_fenicsx.surrogate.ship import SHIPPED_DIR, ShippedTileWarning, read_manifest
from fabric_fenicsx.surrogate.table import FILL_WEAKER, R_LIMIT, WARP_WEAKER, Surrogate
from conftest import COARSE

FABRIC = zylon_as("max")
STALE = "the shipped tiles are not those of the default table now: run `fabric-fenicsx surrogate ship`"


def _default_entry():
    """The manifest's entry of the demo scenes' table (Zylon AS, bending max, default settings)."""
    entries = [t for t in read_manifest()["tables"]
               if t["fabric"] == "zylon_as" and t.get("bending") == "max" and not t.get("settings")]
    assert len(entries) == 1, "tables.json lists no (or several) default Zylon AS tables"
    return entries[0]


def _table(**kw) -> Surrogate:
    return Surrogate(FABRIC, progress=False, workers=1, **kw)


def _shipped_values(sur: Surrogate, layer: str, a: int, b: int) -> np.ndarray:
    name = sur._tile_name(layer, a, b)
    with np.load(SHIPPED_DIR / f"surrogate-{sur.key}" / f"{name}.npz") as f:
        return f["values"]


def _middle(entry: dict, layer: str) -> tuple[int, int]:
    a, b = entry["tiles"][layer][len(entry["tiles"][layer]) // 2].split("_")
    return int(a), int(b)


def _node_strains(sur: Surrogate, a: int, b: int):
    """A grid node in the middle of tile (a, b) (its interpolation taps stay in the tile) and its
    indices within the tile."""
    i, j = sur.tile // 2, sur.tile // 2
    return sur.E_lo + sur.h * (a * sur.tile + i), sur.E_lo + sur.h * (b * sur.tile + j), i, j


def test_the_demo_table_is_shipped_whole_and_every_tile_passes_its_check():
    entry = _default_entry()
    sur = _table(cache_dir=False)
    assert entry["key"] == sur.key, STALE
    folder = SHIPPED_DIR / f"surrogate-{sur.key}"
    names = [f"{layer}_{t}.npz" for layer in ("intact", "damaged") for t in entry["tiles"][layer]]
    assert sorted(p.name for p in folder.iterdir()) == sorted(names)
    assert len(entry["tiles"]["damaged"]) >= 20 and set(entry["tiles"]["damaged"]) <= set(entry["tiles"]["intact"])
    seed = ship_module.ShippedTiles(sur.key)
    nq, nr = 6, sur.r_nodes
    for layer in ("intact", "damaged"):
        for t in entry["tiles"][layer]:
            a, b = map(int, t.split("_"))
            n1, n2 = len(sur._tile_nodes(a)), len(sur._tile_nodes(b))
            shape = (n1, n2, nq) if layer == "intact" else (2, n1, n2, nr - 1, nq)
            assert seed.load(sur._tile_name(layer, a, b), shape) is not None, t
    size = sum(p.stat().st_size for p in SHIPPED_DIR.rglob("*") if p.is_file())
    assert size < 6e6, f"the shipped tiles take {size / 1e6:.1f} MB"


def test_a_shipped_tile_is_read_when_the_cache_is_empty(tmp_path):
    entry = _default_entry()
    sur = _table(cache_dir=tmp_path)
    assert sur.key == entry["key"], STALE
    a, b = _middle(entry, "intact")
    E1, E2, i, j = _node_strains(sur, a, b)
    P1, P2, mu1, mu2 = sur.evaluate(E1, E2, 1.0, 1.0, tension_only=False)
    assert sur.solves == 0 and sur.shipped.used >= 1 and sur.shipped.rejected == 0
    node = _shipped_values(sur, "intact", a, b)[i, j]
    np.testing.assert_allclose([P1, P2, mu1, mu2], node[:4], rtol=1e-9, atol=1e-9 * abs(node[:2]).max())
    name = sur._tile_name("intact", a, b)                     # and copied into the cache
    copied = tiles.load_tile(sur.cache_dir / f"{name}.npz", sur.key, (sur.tile, sur.tile, 6), name)
    np.testing.assert_array_equal(copied, _shipped_values(sur, "intact", a, b))
    # the switch: without the shipped tiles the same tile is solved (and equals them to the
    # round-off of the solver on another CPU: 1e-14 measured)
    solved = _table(cache_dir=tmp_path / "other", shipped=False)
    np.testing.assert_allclose(solved.evaluate(E1, E2, 1.0, 1.0, tension_only=False), (P1, P2, mu1, mu2),
                               rtol=1e-12)
    assert solved.solves == sur.tile ** 2


def _flip_a_value_byte(path):
    """Change one byte inside the compressed values of a shipped tile file."""
    with zipfile.ZipFile(path) as z:
        info = z.getinfo("values.npy")
    data = bytearray(path.read_bytes())
    name_len, extra_len = (int.from_bytes(data[info.header_offset + k:info.header_offset + k + 2], "little")
                           for k in (26, 28))
    start = info.header_offset + 30 + name_len + extra_len
    data[start + info.compress_size // 2] ^= 0xFF
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("fault", ["changed byte", "another tile's file", "another table's key"])
def test_a_shipped_tile_failing_its_check_is_solved_with_a_warning(tmp_path, fault):
    entry = _default_entry()
    ref = _table(cache_dir=False)
    assert ref.key == entry["key"], STALE
    a, b = _middle(entry, "intact")
    fabric = FABRIC.replace(density=1561.0) if fault == "another table's key" else FABRIC
    sur = Surrogate(fabric, progress=False, workers=1, cache_dir=tmp_path / "cache",
                    shipped=tmp_path / "seed")
    target = tmp_path / "seed" / f"surrogate-{sur.key}" / f"intact_{a}_{b}.npz"
    target.parent.mkdir(parents=True)
    source = f"intact_{a}_{b + 1 if b + 1 < ref.n_tiles else b - 1}.npz" if fault == "another tile's file" \
        else f"intact_{a}_{b}.npz"
    shutil.copyfile(SHIPPED_DIR / f"surrogate-{ref.key}" / source, target)
    if fault == "changed byte":
        _flip_a_value_byte(target)
    sur = Surrogate(fabric, progress=False, workers=1, cache_dir=tmp_path / "cache", shipped=tmp_path / "seed")
    E1, E2, i, j = _node_strains(sur, a, b)
    with pytest.warns(ShippedTileWarning, match=f"intact_{a}_{b}.npz fails its check"):
        P1 = sur.evaluate(E1, E2, 1.0, 1.0, tension_only=False)[0]
    assert sur.solves == sur.tile ** 2 and sur.shipped.rejected == 1 and sur.shipped.used == 0
    if fault != "another table's key":          # the tile solved instead is the one shipped
        node = _shipped_values(ref, "intact", a, b)[i, j]
        assert float(P1) == pytest.approx(node[0], rel=1e-9, abs=1e-6)
    # the solved tile went into the cache: the next surrogate reads it there, without a warning
    again = Surrogate(fabric, progress=False, workers=1, cache_dir=tmp_path / "cache", shipped=tmp_path / "seed")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShippedTileWarning)
        assert again.evaluate(E1, E2, 1.0, 1.0, tension_only=False)[0] == P1
    assert again.solves == 0


def test_the_shipped_tiles_are_what_the_unit_cell_gives_now():
    """One intact tile and two blocks of a damaged one (r at its limit -> 0 with the warp
    weaker, a middle r with the fill weaker) solved afresh equal the shipped values to 1e-12 of
    each quantity's largest magnitude: a change of the unit cell's numbers that keeps the cache
    key makes the shipped tiles stale, and this fails."""
    entry = _default_entry()
    sur = _table(cache_dir=False)
    assert sur.key == entry["key"], STALE
    E = sur.E_lo + sur.h * np.arange(sur.nE)
    tiles._worker_init(FABRIC.to_dict(), sur.n_elements)

    def close(fresh, shipped):
        scale = np.abs(shipped).reshape(-1, shipped.shape[-1]).max(axis=0)
        assert np.all(np.abs(fresh - shipped) <= 1e-12 * scale), np.max(np.abs(fresh - shipped) / scale)

    a, b = _middle(entry, "intact")
    _, fresh = tiles._solve_block(("i", (1.0, 1.0), E[sur._tile_nodes(a)], E[sur._tile_nodes(b)]))
    close(fresh, _shipped_values(sur, "intact", a, b))
    a, b = _middle(entry, "damaged")
    shipped = _shipped_values(sur, "damaged", a, b)
    for case, k in ((WARP_WEAKER, 0), (FILL_WEAKER, sur.r_nodes // 2)):
        r = max(sur.r_grid[k], R_LIMIT)
        alpha = (r, 1.0) if case == WARP_WEAKER else (1.0, r)
        _, fresh = tiles._solve_block(("d", alpha, E[sur._tile_nodes(a)], E[sur._tile_nodes(b)]))
        close(fresh, shipped[case, :, :, k])


# ---------------------------------------------------------------------------- surrogate ship
def test_ship_solves_the_listed_tiles_and_those_of_a_cache(tmp_path, capsys):
    """``fabric-fenicsx surrogate ship --shipped DIR`` on a coarse table: the listed tile and
    the one a run's cache holds are solved, written compressed under the current key, the list
    is rewritten with them, a folder of an old key goes, and a surrogate then reads them."""
    settings = {k: COARSE[k] for k in ("resolution", "r_nodes", "tile")}
    root = tmp_path / "shipped"
    (root / "surrogate-0123456789abcdef0123").mkdir(parents=True)          # an old key's folder
    (root / "tables.json").write_text(json.dumps({"tables": [
        {"fabric": "zylon_as", "bending": "max", "settings": settings, "key": "old",
         "tiles": {"intact": ["1_1"], "damaged": []}}]}))
    run_cache = tmp_path / "run-cache"
    visited = Surrogate(FABRIC, cache_dir=run_cache, shipped=False, workers=1, **COARSE)
    visited.ensure_tiles("intact", [(2, 2)])
    assert main(["surrogate", "ship", "--shipped", str(root), "--add-from", str(run_cache),
                 "--workers", "1"]) == 0
    assert "shipped 1 table(s)" in capsys.readouterr().out
    entry = read_manifest(root)["tables"][0]
    assert entry["key"] == visited.key and entry["tiles"] == {"intact": ["1_1", "2_2"], "damaged": []}
    assert sorted(p.name for p in root.iterdir()) == ["surrogate-" + visited.key, "tables.json"]
    files = sorted((root / f"surrogate-{visited.key}").iterdir())
    assert [p.name for p in files] == ["intact_1_1.npz", "intact_2_2.npz"]
    with zipfile.ZipFile(files[1]) as z:
        assert z.getinfo("values.npy").compress_type == zipfile.ZIP_DEFLATED
    reader = Surrogate(FABRIC, cache_dir=tmp_path / "empty", shipped=root, workers=1, **COARSE)
    reader.ensure_tiles("intact", [(1, 1), (2, 2)])
    assert reader.solves == 0 and reader.shipped.used == 2
    np.testing.assert_array_equal(reader.intact[16:24, 16:24], visited.intact[16:24, 16:24])


def test_ship_names_a_bad_list(tmp_path):
    (tmp_path / "tables.json").write_text('{"tables": [{"fabric": "zylon_as"}]}')
    with pytest.raises(SystemExit, match="tables.json: not a list of shipped surrogate tables"):
        main(["surrogate", "ship", "--shipped", str(tmp_path)])
