"""Typed messages: every message round-trips through its JSON, refuses other schemas and versions by name, and
the JSON the pipeline writes parses back into the same objects (scene from the placer, labels from a render,
detections as the node publishes them, a dataset's annotation file)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from zebra_sim_ros.dataset.generate import GenerateConfig, generate
from zebra_sim_ros.messages import (
    Datum,
    Detection,
    Detections,
    FrameAnnotation,
    Labels,
    MessageFormatError,
    Scene,
    Stamp,
    stamp_ns,
)
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.world.world import World
from zebra_sim_ros.zebra.asset import ZebraLibrary


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("msgs")
    generate(GenerateConfig(out=str(out), frames=3, strategy="closeby", seed=21, width=256, height=144,
                            val_fraction=0.0, depth="none", placer={"count_min": 5, "count_max": 12}),
             progress=lambda *a: None)
    return out


def test_stamp_helper() -> None:
    assert stamp_ns(3, 250) == 3_000_000_250
    s = Stamp.from_ns(12_000_000_007)
    assert (s.sec, s.nanosec, s.ns) == (12, 7, 12_000_000_007)
    assert Stamp.from_dict(s.to_dict()) == s and Stamp(1, 5) < Stamp(2, 0)


def test_scene_round_trips_and_refuses_other_schemas(savanna: World, library: ZebraLibrary) -> None:
    scene = Placer(PlacerConfig.from_params({"seed": 9, "count_max": 40, "ground_recolor": 1.0}), savanna,
                   library).scene(2)
    text = scene.to_json()
    back = Scene.from_json(text)
    assert back == scene and back.to_json() == text  # same object, same bytes
    assert scene.placed == len(json.loads(text)["zebras"]) > 0 and not scene.ground.is_identity
    assert scene.camera("drone_1").frame_id == "drone_1/camera_optical"
    assert scene.datum == Datum(-2.3, 34.8, 1550.0) == back.datum  # the placer's defaults: map in the Serengeti
    old = {k: v for k, v in json.loads(text).items() if k != "datum"}  # a scene from before scenes carried it
    before = Scene.from_json(json.dumps(old))
    assert before.datum is None and "datum" not in before.to_dict()
    with pytest.raises(MessageFormatError, match="no camera 'drone_9'"):
        scene.camera("drone_9")
    d = json.loads(text)
    for broken, named in (({**d, "version": 2}, "version 2"), ({**d, "schema": "x"}, "not a zebra_sim_ros/scene"),
                          ({k: v for k, v in d.items() if k != "cameras"}, "lacks 'cameras'"),
                          ({**d, "zebras": [{"id": 1}]}, "malformed"),
                          ({**d, "world": "savanna"}, "malformed: AttributeError"),  # not an object
                          ({**d, "rectangle": [0, 0]}, "malformed: AttributeError"),
                          ({**d, "step": float("inf")}, "malformed: OverflowError"),  # JSON's Infinity
                          ({**d, "datum": {**d["datum"], "latitude_deg": 91}}, "datum latitude 91.0 deg"),
                          ({**d, "datum": {**d["datum"], "latitude_deg": -2.4}},
                           r"datum latitude -2.4 deg is not the lighting's -2.3 deg"),
                          ({**d, "lighting": {**d["lighting"], "latitude_deg": float("nan")}},
                           r"is not the lighting's nan deg"),
                          ({**d, "datum": {"latitude_deg": 1.0}}, "malformed: KeyError 'longitude_deg'"),
                          ({**d, "datum": {"latitude_deg": 1.0, "longitude_deg": 2.0}},
                           "malformed: KeyError 'altitude_m'")):
        with pytest.raises(MessageFormatError, match=named):
            Scene.from_json(json.dumps(broken))
    with pytest.raises(MessageFormatError, match="not JSON"):
        Scene.from_json("{")
    with pytest.raises(ValueError, match="not the lighting's"):  # built, not parsed: the same rule
        replace(scene, datum=Datum(45.0, 34.8, 1550.0))


def test_labels_and_annotations_written_by_generate_parse_back(dataset: Path) -> None:
    files = sorted((dataset / "annotations").glob("*.json"))
    assert len(files) == 3
    seen = 0
    for path in files:
        text = path.read_text()
        meta = FrameAnnotation.from_json(text)
        assert meta.to_json() == text  # the file is exactly the typed annotation's JSON
        labels = meta.labels
        assert Labels.from_json(labels.to_json()) == labels
        assert labels.width == 256 and labels.camera == meta.camera.name
        for z in labels.zebras:
            assert z.instance == z.id + 1 and (z.rle is not None) == (z.kept or z.dont_care or not z.is_zebra)
            assert z.kept == (z.drop_reason is None)
        lines = (dataset / "labels" / "train" / f"{meta.frame}.txt").read_text().split()
        assert len(lines) == 5 * len(labels.kept)
        seen += len(labels.zebras)
    assert seen > 0
    d = json.loads(files[0].read_text())["labels"]
    with pytest.raises(MessageFormatError, match="labels schema version 7"):
        Labels.from_dict({**d, "version": 7})


def test_detections_round_trip_as_the_node_publishes_them() -> None:
    from zebra_sim_ros.nodes.detector import detections_message

    rows = np.array([[10.123, 20.456, 30.789, 40.0, 0.91234, 0], [1, 2, 3, 4, 0.5, 0]], np.float32)
    msg = detections_message(Stamp(4, 2), "drone_0/camera_optical", 320, 180, rows, ("zebra",))
    first = msg.detections[0]  # boxes to 0.01 px, scores to 1e-4, as published
    assert first.box_xyxy == pytest.approx((10.12, 20.46, 30.79, 40.0), abs=1e-9)
    assert first.score == pytest.approx(0.9123, abs=1e-9) and (first.class_id, first.class_name) == (0, "zebra")
    assert isinstance(first, Detection) and len(msg.detections) == 2
    d = json.loads(msg.to_json())
    assert d["schema"] == "zebra_sim_ros/detections" and d["detections"][0]["class"] == 0
    assert Detections.from_json(msg.to_json()) == msg
    with pytest.raises(MessageFormatError, match="lacks 'detections'"):
        Detections.from_json(json.dumps({"schema": "zebra_sim_ros/detections", "version": 1, "stamp": d["stamp"]}))
