"""Configurations and stores written by older versions of shapedb read as they were built."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

import shapedb
from shapedb.config import migrations
from shapedb.config.core import (
    CloudConfig,
    Config,
    DescriptorConfig,
    FieldVectorConfig,
    KernelConfig,
    LightFieldConfig,
    MDBDConfig,
    RerankConfig,
)
from shapedb.config.part import PartConfig
from shapedb.config.surface_words import SurfaceWordsConfig
from shapedb.errors import ConfigError

STORE_LAYOUT1 = Path(__file__).resolve().parents[1] / "data" / "store_layout1"

# Literal configurations as older versions stored them (layout 1: a flat kernel section).
PAPER_ERA = (
    '{"kernel": {"la": 0.75, "lam": 1.0, "lb": 0.75, "n_r": 32, "t": 10, "w": 0.9}, '
    '"mdbd": {"canonical_frame": true, "contact_tol_cells": 0.5, "frame_resolution": 48, '
    '"min_radius_cells": 0.5, "n_balls": 512, "padding_cells": 2, "refine": true, '
    '"resolution": 128, "tie_cells": 1.5}}'
)
METHOD_ERA = '{"kernel": {"la": 0.75, "lam": 1.0, "lb": 0.75, "method": "mdbd", "n_r": 32, "t": 10, "w": 0.9}}'
VIEWS_ERA = (
    '{"kernel": {"descriptor": 2, "la": 0.75, "lam": 1.0, "lb": 0.75, "method": "mdbd", '
    '"n_r": 32, "t": 10, "view_cells": 4.0, "w": 0.9}, "mdbd": {"resolution": 64, '
    '"tie_rule": "middle"}}'
)
RECONSTRUCT_ERA = (
    '{"kernel": {"descriptor": 4, "la": 0.75, "lam": 1.0, "lb": 0.75, "method": "mdbd", '
    '"n_r": 32, "reconstruct": true, "t": 10, "view_cells": 0.0, "w": 0.9}, '
    '"mdbd": {"resolution": 64, "tie_rule": "middle"}}'
)
LAST_FLAT = (
    '{"kernel": {"descriptor": 3, "la": 0.75, "lam": 1.0, "lb": 0.75, "method": "mdbd", '
    '"n_r": 32, "reconstruct": false, "reconstruct_depth": 7, "t": 10, "view_cells": 4.0, '
    '"w": 0.9}, "mdbd": {"canonical_frame": true, "contact_tol_cells": 1.0, '
    '"frame_resolution": 48, "min_radius_cells": 0.5, "n_balls": 32, "padding_cells": 2, '
    '"refine": true, "resolution": 24, "tie_cells": 1.0, "tie_rule": "middle"}}'
)


def test_the_oldest_layout_is_the_papers_kernel_and_the_first_tie_rule() -> None:
    cfg = Config.from_json(PAPER_ERA)
    assert cfg.kernel == KernelConfig(method="paper")
    assert cfg.descriptor == DescriptorConfig(version=1)
    assert cfg.cloud == CloudConfig(view_cells=0.0, reconstruct=False, reconstruct_depth=8)
    assert cfg.mdbd == MDBDConfig(
        contact_tol_cells=0.5, tie_rule="first", sheet_cells=0.0, sheet_rule="whole"
    )


def test_each_later_field_takes_the_value_that_built_the_store() -> None:
    cfg = Config.from_json(METHOD_ERA)
    assert cfg.kernel.method == "mdbd" and cfg.descriptor.version == 1
    assert cfg.mdbd == MDBDConfig()  # no mdbd section stored: today's defaults
    cfg = Config.from_json(VIEWS_ERA)
    assert cfg.descriptor.version == 2 and cfg.cloud == CloudConfig(4.0, False, 8)
    assert cfg.mdbd == MDBDConfig(resolution=64, sheet_cells=0.0, sheet_rule="whole")
    cfg = Config.from_json(RECONSTRUCT_ERA)
    assert cfg.descriptor.version == 4 and cfg.cloud == CloudConfig(0.0, True, 8)
    cfg = Config.from_json(LAST_FLAT)
    assert cfg == _layout1_store_config()


def test_nothing_stored_is_todays_defaults_but_the_stage_the_layout_predates() -> None:
    # a dict without ``layout`` is layout 1, written before re-ranking: no stage
    # (and the light fields the product kept when the section came: unused without a stage)
    plain = Config().with_options(
        rerank="none", lf_source="balls", lf_resolution=64, lf_centre="volume"
    )
    plain = replace(plain, light_field=replace(plain.light_field, framing="sphere"))
    # and no field vectors, none fused (the sections' own defaults are the legacy ones)
    plain = replace(plain, field_vector=FieldVectorConfig(), surface_words=SurfaceWordsConfig())
    assert Config().rerank.scorer == "lightfield"
    assert Config.from_dict({}) == plain
    assert Config.from_dict({"kernel": {}, "mdbd": {}}) == plain
    assert Config.from_dict({"layout": migrations.LAYOUT}) == Config()


def test_todays_layout_round_trips_and_later_fields_take_their_legacy_value() -> None:
    cfg = _layout1_store_config()
    assert json.loads(cfg.to_json())["layout"] == migrations.LAYOUT
    assert Config.from_json(cfg.to_json()) == cfg
    stored = cfg.to_dict()
    del stored["cloud"]["reconstruct"], stored["mdbd"]["tie_rule"]
    again = Config.from_dict(stored)
    assert again.cloud.reconstruct is False and again.mdbd.tie_rule == "first"


def test_unknown_fields_are_refused_in_every_layout() -> None:
    with pytest.raises(ConfigError, match="colour"):
        Config.from_dict({"kernel": {"n_r": 32, "colour": "red"}})
    with pytest.raises(ConfigError, match="colour"):
        Config.from_dict({**Config().to_dict(), "cloud": {"colour": "red"}})
    with pytest.raises(ConfigError, match="optics"):
        Config.from_dict({**Config().to_dict(), "optics": {}})


def test_upgrading_leaves_its_argument_alone() -> None:
    old = json.loads(LAST_FLAT)
    migrations.upgrade_config(old)
    assert old == json.loads(LAST_FLAT)


def test_part_index_configurations_of_every_layout() -> None:
    flat = '{"hops": 2, "la": 0.75, "lam": 1.0, "lb": 0.75, "n_r": 10, "t": 10, "w": 0.9}'
    # the paper's vector on the stored contact graph, as indexes held before
    assert PartConfig.from_dict(json.loads(flat)) == PartConfig(
        size=0.0, centre=0.0, contact_tol_cells=0.0
    )
    later = (
        '{"centre": 8.0, "contact_tol_cells": 0.5, "hops": 1, "la": 0.75, "lam": 1.0, '
        '"lb": 0.75, "n_r": 5, "size": 4.0, "t": 10, "w": 0.9}'
    )
    assert PartConfig.from_dict(json.loads(later)) == PartConfig().with_options(hops=1, n_r=5)
    cfg = PartConfig().with_options(n_r=7, centre=1.0)
    assert PartConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg


def _layout1_store_config() -> Config:
    return Config(
        mdbd=MDBDConfig(
            resolution=24, n_balls=32, tie_cells=1.0, sheet_cells=0.0, sheet_rule="whole"
        ),
        kernel=KernelConfig(),
        descriptor=DescriptorConfig(version=3),
        cloud=CloudConfig(view_cells=4.0, reconstruct=False, reconstruct_depth=7),
        rerank=RerankConfig(scorer="none"),  # written before re-ranking stages
        # before the light fields: those the product kept when the section came
        light_field=LightFieldConfig(
            n_fields=3, resolution=64, n_balls=2048, source="balls", framing="sphere"
        ),
        # before the field vectors and the surface words: none stored
        field_vector=FieldVectorConfig(),
        surface_words=SurfaceWordsConfig(),
    )


def _box_obj(path: Path, extents: tuple[float, float, float]) -> Path:
    import trimesh

    trimesh.creation.box(extents=extents).export(path)
    return path


def test_a_store_written_with_the_previous_layout_opens_and_searches(tmp_path: Path) -> None:
    pytest.importorskip("faiss")
    path = tmp_path / "old"
    shutil.copytree(STORE_LAYOUT1, path, ignore=shutil.ignore_patterns("README.md"))
    assert "layout" not in json.loads((path / "manifest.json").read_text())["config"]
    db = shapedb.connect(path, create=False)
    assert db.config == _layout1_store_config()
    assert db.get("rods1").config == db.config  # each row's own stored configuration
    # the distances this store gave when it was written (shapedb at cf19ee1)
    hits = db.search("rods1", k=6)
    assert [h.name for h in hits] == ["rods1", "rods2", "rods0", "boxes1", "boxes2", "boxes0"]
    assert [h.distance for h in hits] == pytest.approx(
        [0.0, 1.460632, 1.550988, 4.291364, 4.326794, 6.963643], abs=1e-5
    )
    # a model file is featurised with the store's configuration, as it was then
    query = _box_obj(tmp_path / "rods1.obj", (0.7, 0.7, 4))
    hits = db.search(str(query), k=3)
    assert [h.name for h in hits] == ["rods1", "rods2", "rods0"]
    assert [h.distance for h in hits] == pytest.approx([0.0, 1.460632, 1.550988], abs=1e-5)
    # new rows go in beside the old ones, and the store still reads whole
    report = db.ingest([str(_box_obj(tmp_path / "slab.obj", (1, 1.5, 1)))], workers=1)
    assert len(report.ingested) == 1
    again = shapedb.connect(path, create=False)
    assert again.config == _layout1_store_config() and len(again) == 7
    assert again.get("slab").config == again.config
    # written before the field vectors: neither the old rows nor the new one carry one
    assert again.get("slab").field_vector is None and again.get("rods1").field_vector is None
    assert [h.name for h in again.search("rods1", k=3)] == ["rods1", "rods2", "rods0"]


def test_stores_written_before_sheets_never_thicken_and_keep_their_fingerprint(
    tmp_path: Path,
) -> None:
    old = _layout1_store_config()
    assert old.mdbd.sheet_cells == 0.0  # sheets failed then: records were built without
    path = tmp_path / "old"
    shutil.copytree(STORE_LAYOUT1, path, ignore=shutil.ignore_patterns("README.md"))
    db = shapedb.connect(path, create=False)
    stored = db.shapes(["config_fingerprint"]).column("config_fingerprint").to_pylist()
    assert set(stored) == {old.fingerprint} == {db.config.fingerprint}
    assert (
        Config().mdbd.sheet_cells > 0
        and Config().fingerprint
        != replace(Config(), mdbd=replace(Config().mdbd, sheet_cells=0.0)).fingerprint
    )


def test_stores_of_earlier_layouts_search_without_a_reranking_stage() -> None:
    stored = Config().to_dict()
    del stored["rerank"]
    stored["layout"] = 2
    assert Config.from_dict(stored).rerank.scorer == "none"
    assert Config.from_json(LAST_FLAT).rerank.scorer == "none"
    with pytest.raises(ConfigError, match="rerank"):
        Config.from_dict({**Config().to_dict(), "rerank": {"scorer": "teleport"}})


def test_layout_5_stores_drop_the_stage_numbers_and_the_retired_scorer() -> None:
    """A layout-5 store kept the stage's numbers (``lf_fusion``, ``rerank_*``) and could use
    the adaptive scorer: it reads today's stage, and an adaptive store the descriptor alone."""
    stored = Config().to_dict()
    stored["layout"] = 5
    stored["lf_fusion"] = {"weight": 4.0, "pool": 0, "shared_neighbours": 0}
    stored["rerank"] = {"scorer": "lightfield", "candidates": 50, "ratio": 0.35}
    assert Config.from_dict(stored) == Config()
    stored["rerank"]["scorer"] = "adaptive"
    assert Config.from_dict(stored).rerank.scorer == "none"


def test_light_fields_stored_before_the_fills_read_as_the_plain_discs() -> None:
    today = Config().with_options(rerank="lightfield")
    filled = replace(today, light_field=replace(today.light_field, edges=True, close_px=1))
    stored = filled.to_dict()
    assert Config.from_dict(stored).light_field == filled.light_field
    for name in ("edges", "dilate_px", "close_px"):
        del stored["light_field"][name]
    old = Config.from_dict(stored).light_field
    assert (old.edges, old.dilate_px, old.close_px) == (False, 0.0, 0)
    assert old.n_fields == filled.light_field.n_fields
    # a store of a layout before the light fields: the plain discs too
    del stored["light_field"]
    stored["layout"] = 3
    before = Config.from_dict(stored).light_field
    assert (before.edges, before.dilate_px, before.close_px) == (False, 0.0, 0)


def test_light_fields_stored_before_the_longer_packing_read_as_the_decompositions_balls() -> None:
    longer = Config().with_options(rerank="lightfield", lf_source="balls", lf_n_balls=1024)
    assert longer.light_field.n_balls == 1024 and longer.light_field_tail == 1024 - 512
    stored = longer.to_dict()
    assert Config.from_dict(stored) == longer
    del stored["light_field"]["n_balls"]
    old = Config.from_dict(stored)
    assert old.light_field.n_balls == 0 and old.light_field_tail == 0
    # no light fields stored: no tail, whatever the section says
    assert longer.with_options(rerank="none").light_field_tail == 0
    assert longer.with_options(lf_n_balls=300).light_field_tail == 0


def test_light_fields_stored_before_the_source_read_as_the_balls() -> None:
    field = Config().with_options(rerank="lightfield", lf_source="field")
    assert field.light_field_inside and field.light_field_tail == 0
    stored = field.to_dict()
    assert stored["light_field"]["source"] == "field"
    assert Config.from_dict(stored) == field
    assert Config.from_json(field.to_json()) == field
    del stored["light_field"]["source"]
    old = Config.from_dict(stored)
    assert old.light_field.source == "balls" and not old.light_field_inside
    assert old.light_field_tail == old.light_field.n_balls - old.mdbd.n_balls
    # a store of a layout before the light fields: the balls too
    del stored["light_field"]
    stored["layout"] = 3
    assert Config.from_dict(stored).light_field.source == "balls"
    # no light fields stored: nothing to keep
    assert not field.with_options(rerank="none").light_field_inside
    with pytest.raises(ConfigError, match="lf_source"):
        Config().with_options(lf_source="mesh")


def test_light_fields_stored_before_the_centre_read_about_the_volume_centroid() -> None:
    today = Config().with_options(rerank="lightfield")
    assert today.light_field.source == "field" and today.light_field.centre == "surface"
    stored = today.to_dict()
    assert Config.from_dict(stored) == today
    del stored["light_field"]["centre"]
    assert Config.from_dict(stored).light_field.centre == "volume"
    del stored["light_field"]
    stored["layout"] = 3
    assert Config.from_dict(stored).light_field.centre == "volume"
    with pytest.raises(ConfigError, match="lf_centre"):
        Config().with_options(lf_centre="middle")


def test_light_fields_stored_before_the_framing_read_in_the_sphere_s_frame() -> None:
    today = Config()
    assert today.light_field.framing == "view"
    stored = today.to_dict()
    assert Config.from_dict(stored) == today
    del stored["light_field"]["framing"]
    assert Config.from_dict(stored).light_field.framing == "sphere"
    del stored["light_field"]
    stored["layout"] = 3
    assert Config.from_dict(stored).light_field.framing == "sphere"


def test_stores_written_before_the_field_vectors_keep_none() -> None:
    new = Config()
    assert new.stores_field_vectors
    stored = new.to_dict()
    assert stored["layout"] == migrations.LAYOUT and Config.from_dict(stored) == new
    # a layout-4 store: no field_vector section (its lf_fusion section is dropped)
    del stored["field_vector"], stored["surface_words"]
    stored["layout"] = 4
    stored["lf_fusion"] = {"weight": 8.0}
    old = Config.from_dict(stored)
    assert old.field_vector == FieldVectorConfig() and not old.field_vector.enabled
    assert not old.stores_field_vectors
    # everything else as the store wrote it
    assert replace(old, field_vector=new.field_vector, surface_words=new.surface_words) == new
    # a layout-3 store: neither light fields nor field vectors
    del stored["lf_fusion"], stored["light_field"]
    stored["layout"] = 3
    older = Config.from_dict(stored)
    assert not older.field_vector.enabled


def test_stores_written_before_the_surface_words_keep_none() -> None:
    new = Config()
    assert new.stores_surface_words
    stored = new.to_dict()
    del stored["surface_words"]
    stored["layout"] = 6
    old = Config.from_dict(stored)
    assert old.surface_words == SurfaceWordsConfig() and not old.stores_surface_words
    assert replace(old, surface_words=new.surface_words) == new
    # a store without the stage keeps no words, whatever the section says
    assert not new.with_options(rerank="none").stores_surface_words


def test_stores_written_before_the_view_words_keep_none() -> None:
    new = Config()
    assert new.stores_view_words
    stored = new.to_dict()
    assert stored["surface_words"] == {"enabled": True, "view_words": True}
    # a layout-7 store: surface words without the view words' field
    del stored["surface_words"]["view_words"]
    stored["layout"] = 7
    old = Config.from_dict(stored)
    assert old.surface_words == SurfaceWordsConfig(enabled=True, view_words=False)
    assert old.stores_surface_words and not old.stores_view_words
    assert replace(old, surface_words=new.surface_words) == new
    # no view words without the surface words, nor without the stage
    off = replace(new, surface_words=SurfaceWordsConfig(enabled=False, view_words=True))
    assert not off.stores_view_words
    assert not new.with_options(rerank="none").stores_view_words
    with pytest.raises(ConfigError, match="view_words"):
        SurfaceWordsConfig(enabled=True, view_words="yes")  # type: ignore[arg-type]
