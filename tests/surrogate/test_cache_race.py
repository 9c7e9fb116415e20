"""One tile cache shared by several builders at once (the workers of a cluster on one folder).

No lock is taken (``tiles`` module docstring): two builders that miss the same tile both solve
it and both write it. These tests make that race happen on purpose and check that it only costs
time: both get the same values, the file left passes its checksum, no temporary file is left,
and a reader never sees a half-written file.
"""

import multiprocessing
import threading

import numpy as np

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.surrogate import table as table_module
from fabric_fenicsx.surrogate import tiles
from fabric_fenicsx.surrogate.table import Surrogate
from conftest import COARSE

FABRIC = zylon_as("max")
TILE = (2, 2)
"""An intact tile of the coarse table (8 x 8 nodes: 64 unit-cell solves, a fraction of a second)."""


def _builder(cache, barrier, results):
    """Build tile TILE of the coarse table in ``cache``; wait at ``barrier`` after solving it and
    before writing it, so that both builders have missed it and write it at the same time."""
    real_save = table_module.save_tile

    def save_together(*args, **kwargs):
        barrier.wait(timeout=120)
        real_save(*args, **kwargs)

    table_module.save_tile = save_together
    sur = Surrogate(FABRIC, cache_dir=cache, workers=1, shipped=False, **COARSE)
    sur.ensure_tiles("intact", [TILE])
    ia, jb = sur._tile_nodes(TILE[0]), sur._tile_nodes(TILE[1])
    results.put((sur.solves, sur.intact[ia[0]:ia[-1] + 1, jb[0]:jb[-1] + 1].copy()))


def test_two_processes_building_the_same_tile_at_once(tmp_path):
    ctx = multiprocessing.get_context("fork")
    barrier, results = ctx.Barrier(2), ctx.Queue()
    procs = [ctx.Process(target=_builder, args=(tmp_path, barrier, results)) for _ in range(2)]
    for p in procs:
        p.start()
    got = [results.get(timeout=300) for _ in procs]
    for p in procs:
        p.join(timeout=60)
        assert p.exitcode == 0
    (solves_a, values_a), (solves_b, values_b) = got
    assert solves_a == solves_b == 64                  # both missed the tile and solved it
    np.testing.assert_array_equal(values_a, values_b)
    sur = Surrogate(FABRIC, cache_dir=tmp_path, workers=1, shipped=False, **COARSE)
    files = sorted(p.name for p in sur.cache_dir.iterdir())
    assert files == [f"intact_{TILE[0]}_{TILE[1]}.npz"]   # no temporary file left
    name = sur._tile_name("intact", *TILE)
    on_disk = tiles.load_tile(sur.cache_dir / f"{name}.npz", sur.key, values_a.shape, name)
    assert on_disk is not None                          # passes key, name and checksum
    np.testing.assert_array_equal(on_disk, values_a)
    sur.ensure_tiles("intact", [TILE])
    assert sur.solves == 0


def _hammer(path, key, values, name, n, start):
    start.wait(timeout=120)
    for _ in range(n):
        tiles.save_tile(path, key, values, name)


def test_writers_in_threads_and_processes_never_show_a_reader_a_partial_file(tmp_path):
    """Two processes of three threads each rewrite one tile 40 times while this process reads it:
    every read of the file (once it exists) passes its check and gives the values. (Temporary
    names that differ only by process, as before, collide between threads of one process: the
    reader then sees a file still being written, or a writer finds its file gone.)"""
    rng = np.random.default_rng(0)
    values = rng.standard_normal((16, 16, 6))
    key, name = "k" * 20, "intact_0_0"
    path = tmp_path / f"{name}.npz"
    ctx = multiprocessing.get_context("fork")
    start = ctx.Barrier(3)
    procs = [ctx.Process(target=_process_entry, args=(path, key, values, name, start)) for _ in range(2)]
    for p in procs:
        p.start()
    start.wait(timeout=120)
    reads = bad = 0
    while True:
        running = any(p.is_alive() for p in procs)
        if path.exists():
            got = tiles.load_tile(path, key, values.shape, name)
            reads += 1
            bad += got is None or not np.array_equal(got, values)
        if not running:
            break
    for p in procs:
        p.join(timeout=60)
        assert p.exitcode == 0
    assert reads > 0 and bad == 0, f"{bad} of {reads} reads saw a broken tile file"
    assert [p.name for p in tmp_path.iterdir()] == [path.name]   # no temporary file left


def _process_entry(path, key, values, name, start):
    """Three threads of one process, each rewriting the tile 40 times; exit code 1 if any fails."""
    start.wait(timeout=120)
    inner = threading.Barrier(3)
    errors = []

    def body():
        try:
            _hammer(path, key, values, name, 40, inner)
        except Exception as err:  # reported through the exit code
            errors.append(err)

    threads = [threading.Thread(target=body) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if errors:
        raise SystemExit(1)


def test_temporary_names_differ_between_threads_of_one_process(tmp_path):
    names = set()

    def pick():
        names.add(tiles.temporary_name(tmp_path / "intact_0_0.npz"))

    threads = [threading.Thread(target=pick) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(names) == 8
    assert all(n.parent == tmp_path and n.name.startswith(".intact_0_0.npz.") and n.suffix == ".tmp"
               for n in names)
