"""shapedb check / repair: verify segments against the manifest, rebuild it from data/."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_store import CONFIG, forget_checksums, make_record

from shapedb.errors import StoreError
from shapedb.store.integrity import LOST_AND_FOUND, check, repair
from shapedb.store.store import MANIFEST, Store


@pytest.fixture()
def three(tmp_path: Path) -> Store:
    """A store of three shapes in two commits, with one deletion and one failure."""
    from shapedb.store.schema import Failure

    store = Store.create(tmp_path / "base", CONFIG)
    store.add([make_record("a"), make_record("b")], failures=[Failure("x.obj", "LoadError", "bad")])
    store.add([make_record("c"), make_record("d")])
    store.delete([2])  # rewrites the first segments: retired files stay on disk
    return store


def _names(store: Store) -> list[str]:
    return sorted(store.shapes(["name"]).column("name").to_pylist())


def test_check_passes_on_an_intact_store(three: Store) -> None:
    report = check(three.path)
    assert report.ok and report.damaged == () and report.checked > 0
    assert report.unverified == ()


def test_check_names_each_damaged_or_missing_file(three: Store) -> None:
    shapes = three.files("shapes")
    balls = three.files("balls")
    Path(shapes[0]).unlink()
    data = bytearray(Path(balls[0]).read_bytes())
    data[40] ^= 0xFF  # one flipped byte: same size
    Path(balls[0]).write_bytes(bytes(data))
    report = check(three.path)
    assert not report.ok
    damaged = dict(report.damaged)
    assert damaged[str(Path(shapes[0]).relative_to(three.path))] == "missing"
    assert "checksum" in damaged[str(Path(balls[0]).relative_to(three.path))]
    assert len(damaged) == 2


def test_old_manifests_without_checksums_still_check(three: Store) -> None:
    forget_checksums(three.path)
    report = check(three.path)
    assert report.ok and report.checked == 0 and len(report.unverified) >= 3
    assert _names(Store.open(three.path)) == ["a", "c", "d"]


def test_repair_rebuilds_a_lost_manifest(three: Store) -> None:
    """the data of a store whose manifest was deleted comes back."""
    before = three.shapes().to_pylist()
    (three.path / MANIFEST).unlink()
    with pytest.raises(StoreError, match="manifest.json is missing"):
        check(three.path)
    report = repair(three.path)
    assert report.changed and report.shapes == 3
    store = Store.open(three.path)
    assert store.shapes().to_pylist() == before  # the deleted shape b stays deleted
    assert store.config == CONFIG
    assert store.failures().column("source").to_pylist() == ["x.obj"]
    assert check(three.path).ok and check(three.path).unlisted == ()
    assert report.moved_to is not None and Path(report.moved_to).parent.name == LOST_AND_FOUND
    store.add([make_record("e")])  # a working store: ids continue after the largest
    assert store.ids().tolist() == [1, 3, 4, 5]


def test_repair_drops_what_is_damaged_and_reports_it(three: Store) -> None:
    seg = three.files("shapes")[-1]  # the newest: shapes c and d
    Path(seg).write_bytes(b"garbage")
    report = repair(three.path)
    assert report.changed
    assert any(Path(seg).name in what for what, _ in report.lost)
    store = Store.open(three.path)
    assert check(three.path).ok
    assert _names(store) == ["a"]
    assert len(store.balls()) == store.shapes(["n_balls"]).column("n_balls").to_numpy().sum()


def test_repair_of_an_intact_store_changes_nothing(three: Store) -> None:
    manifest = (three.path / MANIFEST).read_text()
    report = repair(three.path)
    assert not report.changed and report.shapes == 3
    assert (three.path / MANIFEST).read_text() == manifest


def test_repair_rebuilds_a_manifest_missing_a_key(three: Store) -> None:
    manifest = json.loads((three.path / MANIFEST).read_text())
    del manifest["tables"]
    (three.path / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(StoreError, match="key 'tables' is missing"):
        Store.open(three.path)
    assert repair(three.path).shapes == 3
    assert _names(Store.open(three.path)) == ["a", "c", "d"]


def test_a_store_written_before_checksums_checks_and_takes_new_rows(tmp_path: Path) -> None:
    """The store written by cf19ee1 (tests/data/store_layout1): no checksums, no store id."""
    import shutil

    old = Path(__file__).resolve().parents[1] / "data" / "store_layout1"
    root = tmp_path / "old"
    shutil.copytree(old, root)
    (root / "README.md").unlink()
    report = check(root)
    assert report.ok and report.checked == 0 and len(report.unverified) == 3
    assert not repair(root).changed
    store = Store.open(root)
    n = len(store)
    store.add([make_record("new", config=store.config)])
    assert len(store) == n + 1
    report = check(root)
    assert report.ok and report.checked >= 1 and len(report.unverified) == 3


def _set_manifest(store: Store, **changes: object) -> None:
    manifest = json.loads((store.path / MANIFEST).read_text())
    manifest.update(changes)
    (store.path / MANIFEST).write_text(json.dumps(manifest))


def test_check_and_repair_a_next_id_that_would_reuse_an_id(three: Store) -> None:
    _set_manifest(three, next_id=3)  # the store holds ids 1, 3 and 4
    report = check(three.path)
    assert not report.ok and report.damaged == ()
    assert report.conflicts == (
        (
            "manifest.json",
            "next_id 3 is at or below the largest id 4: a new shape would reuse an id",
        ),
    )
    fixed = repair(three.path)
    assert fixed.changed and fixed.lost == () and fixed.shapes == 3
    assert any("next_id 3" in note for note in fixed.notes)
    assert check(three.path).ok and _names(Store.open(three.path)) == ["a", "c", "d"]
    assert Store.open(three.path).add([make_record("e")])[0].id == 5


def _graft(store: Store, other: Store, version: int) -> None:
    """List ``other``'s segments in ``store``'s manifest as if committed at ``version``."""
    manifest = json.loads((store.path / MANIFEST).read_text())
    theirs = json.loads((other.path / MANIFEST).read_text())
    for table in ("shapes", "balls", "edges"):
        for seg in theirs["tables"][table]:
            name = f"{version:08d}-{Path(seg['file']).name.split('-', 1)[1]}"
            (store.path / seg["file"]).parent.mkdir(parents=True, exist_ok=True)
            (other.path / seg["file"]).rename(store.path / "data" / table / name)
            manifest["tables"][table].append(dict(seg, file=f"data/{table}/{name}"))
    (store.path / MANIFEST).write_text(json.dumps(manifest))


def test_two_rows_claiming_one_id_both_survive_repair(three: Store, tmp_path: Path) -> None:
    other = Store.create(tmp_path / "other", CONFIG)
    other.add([make_record("z", n=9)])  # id 1, as "a" in three
    _graft(three, other, version=99)
    report = check(three.path)
    assert not report.ok and report.damaged == ()
    assert report.conflicts[0][0] == "id 1" and "held by 2 rows" in report.conflicts[0][1]
    fixed = repair(three.path)
    assert fixed.lost == () and fixed.shapes == 4
    assert fixed.reassigned == ((1, 5),)
    assert any("'z'" in note and "now id 5" in note for note in fixed.notes)
    store = Store.open(three.path)
    assert check(three.path).ok
    assert _names(store) == ["a", "c", "d", "z"]
    assert store.get(1).name == "a" and store.get(5).name == "z"
    assert len(store.get(5).decomposition.radii) == 9
    assert len(store.get(1).decomposition.radii) == 6
    assert store.add([make_record("e")])[0].id == 6


def test_repair_keeps_the_rows_of_a_segment_whose_row_count_was_edited(three: Store) -> None:
    before = three.shapes().to_pylist()
    manifest = json.loads((three.path / MANIFEST).read_text())
    manifest["tables"]["shapes"][0]["rows"] += 5
    (three.path / MANIFEST).write_text(json.dumps(manifest))
    assert (
        "rows, the manifest records"
        in dict(check(three.path).damaged)[manifest["tables"]["shapes"][0]["file"]]
    )
    fixed = repair(three.path)
    assert fixed.lost == () and fixed.shapes == 3
    assert any("intact ones: they were kept" in note for note in fixed.notes)
    assert Store.open(three.path).shapes().to_pylist() == before and check(three.path).ok


def test_repair_after_data_was_deleted_gives_a_working_store(three: Store) -> None:
    import shutil

    shutil.rmtree(three.path / "data")
    assert not check(three.path).ok
    fixed = repair(three.path)
    assert fixed.changed and fixed.shapes == 0 and len(fixed.lost) >= 3
    assert all((three.path / "data" / t).is_dir() for t in ("shapes", "balls", "edges"))
    store = Store.open(three.path)
    assert store.add([make_record("e")])[0].id == 5  # ids still never reused
    assert check(three.path).ok and _names(store) == ["e"]


@pytest.mark.parametrize("content", [[], ["notes.txt"]])
def test_repair_refuses_a_folder_that_is_no_store(tmp_path: Path, content: list[str]) -> None:
    folder = tmp_path / "plain"
    folder.mkdir()
    for name in content:
        (folder / name).write_text("mine")
    with pytest.raises(StoreError, match="no shapedb store here") as info:
        repair(folder)
    assert "\n" not in str(info.value)
    assert sorted(p.name for p in folder.iterdir()) == content  # no .lock left behind
