"""``rovis eval`` (matching, error metrics, tables, workers, Dask, bad input) and
``rovis bench`` (the pipeline benchmark)."""

from __future__ import annotations

import json
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from rovis import evaluate as ev
from rovis.cli import main
from rovis.evaluate import Book, book_errors, match_books, score_books, yaw_error_deg
from rovis.synth import write_dataset

METHODS = ("closed", "open", "contour")  # the paper's pair and a fast baseline


def _R(yaw_deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _book(center, yaw_deg, size, visible=True) -> Book:
    return Book(np.asarray(center, float), _R(yaw_deg), np.asarray(size, float), visible)


def _without_timing(records: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "timing_ms"} for r in records]


# --------------------------------------------------------------------------- metrics


def test_book_errors_are_estimate_minus_truth():
    true = _book([0.30, 0.40, 0.030], 30.0, [0.200, 0.150, 0.030])
    est = _book([0.304, 0.398, 0.031], 32.0, [0.205, 0.148, 0.032])
    e = book_errors(true, est)
    assert e["x"] == pytest.approx(0.004, abs=1e-12)  # 4 mm
    assert e["y"] == pytest.approx(-0.002, abs=1e-12)
    assert e["z"] == pytest.approx(0.001, abs=1e-12)
    assert e["psi_deg"] == pytest.approx(2.0, abs=1e-9)
    assert e["length"] == pytest.approx(0.005, abs=1e-12)
    assert e["width"] == pytest.approx(-0.002, abs=1e-12)
    assert e["height"] == pytest.approx(0.002, abs=1e-12)
    no_height = Book(est.center, est.R, np.array([0.205, 0.148, np.nan]))
    assert book_errors(true, no_height)["height"] is None


def test_yaw_error_is_taken_modulo_180_and_modulo_90_for_squares():
    rect, square = [0.20, 0.15, 0.03], [0.20, 0.195, 0.03]  # sides 5 cm / 0.5 cm apart
    R = _R(30.0)
    assert yaw_error_deg(R, rect, _R(30.0 + 180.0 + 1.0), rect) == pytest.approx(1.0)
    assert yaw_error_deg(R, rect, _R(30.0 - 179.0), rect) == pytest.approx(1.0)
    assert yaw_error_deg(R, rect, _R(30.0 + 89.0), rect) == pytest.approx(89.0)
    assert yaw_error_deg(R, square, _R(30.0 + 89.0), square) == pytest.approx(-1.0)
    assert yaw_error_deg(R, square, _R(30.0 + 270.0 + 2.0), square) == pytest.approx(2.0)
    # the estimate calls its long side y: its long axis is what is compared
    swapped = [0.15, 0.20, 0.03]
    assert yaw_error_deg(R, rect, _R(30.0 - 90.0 + 0.5), swapped) == pytest.approx(0.5)
    # the truth's long side may be its y axis too
    assert yaw_error_deg(_R(120.0), swapped, _R(30.0 + 0.5), rect) == pytest.approx(0.5)


def test_matching_is_one_to_one_hungarian_within_5_cm():
    truth = [[0.0, 0.0, 0.03], [0.045, 0.0, 0.03]]
    # Greedy nearest-truth would give d0 to book 1 and leave book 0 unmatched (d1 is 7 cm
    # from it); the assignment matches both.
    dets = [[0.025, 0.0, 0.03], [0.070, 0.0, 0.03], [0.30, 0.3, 0.03]]
    assert match_books(truth, dets) == [(0, 0), (1, 1)]
    # a decoy as close to book 0 as d0: still one detection per book, the other is a FP
    books = [_book(c, 0.0, [0.2, 0.15, 0.03]) for c in truth]
    found = [_book(c, 0.0, [0.2, 0.15, 0.03]) for c in dets + [[0.001, 0.0, 0.03]]]
    score = score_books(books, found)
    assert score["found"] == [3, 0]  # the decoy (1 mm) takes book 0, d0 (2 cm) book 1
    assert score["false_positives"] == 2
    assert [m["distance"] for m in score["matches"]] == pytest.approx([0.001, 0.02])
    assert match_books(truth, [[0.0, 0.051, 0.03]]) == []  # 5.1 cm: no match
    assert match_books([], dets) == [] and match_books(truth, np.empty((0, 3))) == []


def test_median_and_95th_percentile_say_what_a_mean_with_one_book_far_off_hides():
    # four books 1 mm off and one 10 cm off (a book found as its neighbour, say): the mean
    # is 20.8 mm, the median 1 mm; the 95th percentile interpolates 80 % of the way from
    # the fourth value to the fifth
    st = ev._stats([0.001, -0.001, 0.001, 0.001, -0.1, None])
    assert st["n"] == 5
    assert st["mean"] == pytest.approx(0.0208)
    assert st["median"] == pytest.approx(0.001)
    assert st["p95"] == pytest.approx(0.001 + 0.8 * 0.099)
    assert ev._stats([None]) == {"max": None, "mean": None, "std": None, "median": None,
                                 "p95": None, "n": 0}
    # a results.json written before these were kept still prints, without their rows
    old = {k: {"max": 0.001, "mean": 0.001, "std": 0.0, "n": 1} for k in ev.ERROR_KEYS}
    s = {"images": 1, "books": 1, "found": 1, "recall": 1.0, "visible_books": 1,
         "visible_found": 1, "recall_visible": 1.0, "false_positives": 0, "fp_per_image": 0.0,
         "errors": old}
    text = ev.method_table("closed", s, None)
    assert "Mean" in text and "Median" not in text


def test_the_books_found_furthest_off_are_listed_worst_first():
    books = [_book([0.1, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03]),
             _book([0.4, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03])]
    dets = [_book([0.1, 0.125, 0.03], 0.0, [0.2, 0.15, 0.03]),  # 25 mm off in Y
            _book([0.402, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03])]  # 2 mm off in X
    score = score_books(books, dets)
    score.update(sources=["height map", "segmentation"], quality=[0.4, 1.0])
    far = {"scene": "0007", "lux": 15.0, "books": [{"visible": True}] * 2,
           "methods": {"closed": score}}
    near = {"scene": "0001", "lux": 500.0, "books": [{"visible": True}],
            "methods": {"closed": score_books(books[:1], [_book([0.1, 0.1005, 0.03], 0.0,
                                                                [0.2, 0.15, 0.03])])}}
    rows = ev.furthest_books([near, far], "closed", n=2)
    assert [(r["scene"], r["truth"]) for r in rows] == [("0007", 0), ("0007", 1)]
    assert rows[0]["worst"] == pytest.approx(0.025)
    assert (rows[0]["source"], rows[0]["quality"], rows[0]["lux"]) == ("height map", 0.4, 15.0)
    assert len(ev.furthest_books([near, far], "closed")) == 3  # all, where fewer than n
    assert ev.furthest_books([near, far], "open") == []
    text = ev.furthest_table(rows)
    assert "0007" in text and "25.0" in text and "height map" in text
    assert "0001" not in text
    # a book with no height, in a record without lux, quality or source: dashes
    bare = dict(rows[0], errors=dict(rows[0]["errors"], height=None))
    for key in ("lux", "quality", "source"):
        bare.pop(key)
    line = ev.furthest_table([bare]).splitlines()[1]
    assert line.split()[:3] == ["0007", "0", "-"] and line.split()[-3:] == ["-", "-", "-"]


def test_summary_statistics_and_recall_of_well_visible_books():
    books = [_book([0.1, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03]),
             _book([0.4, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03]),
             _book([0.4, 0.4, 0.03], 0.0, [0.2, 0.15, 0.03], visible=False)]
    dets = [_book([0.101, 0.1, 0.03], 1.0, [0.2, 0.15, 0.03]),
            _book([0.397, 0.1, 0.03], -3.0, [0.2, 0.15, 0.03]),
            _book([0.8, 0.5, 0.03], 0.0, [0.2, 0.15, 0.03])]  # a false positive
    record = {"books": [{"visible": b.visible} for b in books],
              "methods": {"closed": score_books(books, dets)}}
    s = ev.summarize_method([record, record], "closed")
    assert (s["images"], s["books"], s["found"]) == (2, 6, 4)
    assert s["recall"] == pytest.approx(4 / 6)
    assert (s["visible_books"], s["visible_found"], s["recall_visible"]) == (4, 4, 1.0)
    assert s["fp_per_image"] == 1.0
    x = s["errors"]["x"]  # |X_e| = 1 mm and 3 mm, twice
    assert (x["max"], x["mean"], x["std"], x["n"]) == pytest.approx((0.003, 0.002, 0.001, 4))
    # 1, 1, 3, 3 mm: the median halfway, the 95th percentile 0.85 of the way from the
    # third to the fourth value (linear: position 0.95 x 3), which are equal
    assert (x["median"], x["p95"]) == pytest.approx((0.002, 0.003))
    assert s["errors"]["psi_deg"]["mean"] == pytest.approx(2.0)
    text = ev.method_table("closed", s, ev.PAPER_TABLE_I)
    assert "Max error" in text and "St. deviation" in text and "paper Table I" in text
    assert "Median" in text and "95th percentile" in text
    # the grasp tolerance: 1 and 3 mm off are within 1 cm; 15 mm off is matched, not within
    assert s["within_1cm"] == 4 and "4 of the 4 matched books within 1 cm" in text
    off = {"books": [{"visible": True}],
           "methods": {"closed": score_books(books[:1], [_book([0.1, 0.115, 0.03], 0.0,
                                                               [0.2, 0.15, 0.03])])}}
    s_off = ev.summarize_method([off], "closed")
    assert (s_off["found"], s_off["within_1cm"]) == (1, 0)
    assert ev.lux_band(15.0) == "15-50 lx" and ev.lux_band(1200.0) == "500-1200 lx"
    assert ev.lux_band(10.0) == "<15 lx" and ev.lux_band(None) is None


def _close_off_and_false() -> tuple[list[Book], list[Book]]:
    """Two true books, and three detections: one 1 mm off, one 2 cm off (past the grasp
    tolerance), one a false positive."""
    books = [_book([0.1, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03]),
             _book([0.4, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03])]
    dets = [_book([0.101, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03]),
            _book([0.42, 0.1, 0.03], 0.0, [0.2, 0.15, 0.03]),
            _book([0.8, 0.5, 0.03], 0.0, [0.2, 0.15, 0.03])]
    return books, dets


def test_errors_and_false_positives_by_how_each_book_was_found():
    books, dets = _close_off_and_false()
    score = {**score_books(books, dets), "sources": ["segmentation", "height map", "height map"]}
    record = {"books": [{"visible": True}] * 2, "methods": {"closed": score}}
    by = ev.source_breakdown([record, record], ["closed"])["closed"]
    assert list(by) == ["height map", "segmentation"]  # the most detections first
    hm, seg = by["height map"], by["segmentation"]
    assert (hm["detections"], hm["matched"], hm["false_positives"], hm["over_1cm"]) == (4, 2, 2, 2)
    assert (seg["detections"], seg["matched"], seg["false_positives"], seg["over_1cm"]) == (2, 2, 0, 0)
    assert hm["errors"]["x"]["max"] == pytest.approx(0.02)
    assert seg["errors"]["x"]["max"] == pytest.approx(0.001)
    text = ev.source_table({"closed": by})
    assert "found by" in text and "height map" in text
    # a results.json written before sources were recorded: nothing to say
    old = {"books": record["books"], "methods": {"closed": score_books(books, dets)}}
    assert ev.source_breakdown([old], ["closed"]) == {"closed": {}}


def test_books_counted_and_their_errors_by_the_kind_of_their_cover():
    books, dets = _close_off_and_false()
    # book 0 found 1 mm off by detection 2, book 1 2 cm off by detection 1 (detection and
    # truth indices differ: the breakdown goes by the truth's)
    score = score_books(books, [dets[2], dets[1], dets[0]])
    record = {"books": [{"visible": True, "cover": "desk"}, {"visible": True, "cover": "printed"}],
              "methods": {"closed": score}}
    unfound = {"books": [{"visible": True, "cover": "printed"}, {"visible": True}],  # (no kind)
               "methods": {"closed": score_books(books, [])}}
    by = ev.cover_breakdown([record, record, unfound], ["closed"])["closed"]
    assert list(by) == ["printed", "desk"]  # the most books first
    desk, printed = by["desk"], by["printed"]
    assert (desk["books"], desk["found"], desk["within_1cm"]) == (2, 2, 2)
    assert (printed["books"], printed["found"], printed["within_1cm"]) == (3, 2, 0)
    assert desk["errors"]["x"]["mean"] == pytest.approx(0.001)
    assert printed["errors"]["x"]["mean"] == pytest.approx(0.02)
    # a book exactly 1 cm off is within the grasp tolerance, as in summarize_method; errors
    # are shown in millimetres and degrees
    edge = {"books": [{"visible": True, "cover": "light"}],
            "methods": {"closed": {"matches": [{"truth": 0, "detection": 0, "errors": {
                "x": 0.01, "y": -0.002, "z": 0.003, "psi_deg": 1.5, "length": 0.004,
                "width": -0.005, "height": None}}]}}}
    light = ev.cover_breakdown([edge], ["closed"])["closed"]["light"]
    assert (light["books"], light["found"], light["within_1cm"]) == (1, 1, 1)
    text = ev.cover_table({"closed": {**by, "light": light}})
    row = next(line for line in text.splitlines() if "light" in line).split()
    assert row[1:] == ["1", "1", "1", "10.0", "2.0", "3.0", "1.50", "4.0", "5.0"]
    # truth without kinds (real data, an older results.json): nothing to say
    plain = {"books": [{"visible": True}] * 2, "methods": {"closed": score}}
    assert ev.cover_breakdown([plain], ["closed"]) == {"closed": {}}


def test_detections_counted_by_how_well_they_agree_with_the_images():
    books, dets = _close_off_and_false()
    score = {**score_books(books, dets), "quality": [1.0, 0.85, 0.95],
             "reprojection_error_px": [0.2, 1.0, 2.5]}
    record = {"books": [{"visible": True}] * 2, "methods": {"closed": score}}
    by = ev.agreement_breakdown([record, record], ["closed"])["closed"]
    q, e = by["quality"], by["reprojection_error_px"]
    assert list(q) == ["[0.95, 1]", "[0.9, 0.95)", "[0.8, 0.9)", "[0, 0.8)"]
    assert q["[0.95, 1]"] == {"detections": 4, "within_1cm": 2, "over_1cm": 0,
                              "false_positives": 2}  # 0.95 on the edge: the better band
    assert q["[0.8, 0.9)"] == {"detections": 2, "within_1cm": 0, "over_1cm": 2,
                               "false_positives": 0}
    assert list(e) == ["[0, 0.5]", "(0.5, 1]", "(1, 1.5]", "> 1.5"]
    assert (e["[0, 0.5]"]["within_1cm"], e["(0.5, 1]"]["over_1cm"],
            e["> 1.5"]["false_positives"]) == (2, 2, 2)
    text = ev.agreement_table({"closed": by})
    assert "reprojection error px" in text
    assert re.search(r"\[0\.8, 0\.9\)\s+2\s+0\s+2\s+0\s+0%", text)
    assert re.search(r"\[0, 0\.5\]\s+2\s+2\s+0\s+0\s+100%", text)
    # a value not measured counts in the worst band
    score["quality"] = [float("nan"), 0.85, 0.95]
    assert ev.agreement_breakdown([record], ["closed"])["closed"]["quality"]["[0, 0.8)"] == {
        "detections": 1, "within_1cm": 1, "over_1cm": 0, "false_positives": 0}
    # a results.json written before the measures were recorded: nothing to say
    old = {"books": record["books"], "methods": {"closed": score_books(books, dets)}}
    assert ev.agreement_breakdown([old], ["closed"]) == {"closed": {}}


def test_paper_figures_beside_ours():
    assert ev.paper_reference("closed", "table1") is ev.PAPER_TABLE_I
    assert ev.paper_reference("open", "table2").max == (0.6294, 0.2513, 0.7881, 34.0)
    assert ev.paper_reference("closed", "table2").mean == (0.0101, 0.0054, 0.0038, 4.0)
    assert ev.paper_reference("lsd", "table2") is None


# --------------------------------------------------------------------------- end to end


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("eval") / "ds", protocol="table1", n=2, seed=5)


@pytest.fixture(scope="module")
def serial(dataset) -> ev.Evaluation:
    return ev.evaluate(dataset, METHODS)


def test_eval_cli_with_one_and_two_workers_gives_identical_results(dataset, serial, tmp_path,
                                                                     capsys):
    docs = []
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        assert main(["eval", str(dataset), "--methods", ",".join(METHODS), "--workers",
                     str(workers), "--out", str(out)]) == 0
        captured = capsys.readouterr()
        assert "Max error" in captured.out and "paper Table I" in captured.out
        assert "agrees with the images" in captured.out
        assert "By the true book's cover" in captured.out
        assert "Median" in captured.out and "found furthest off" in captured.out
        assert "0 scenes skipped" in captured.out
        assert "2/2 scenes" in captured.err
        for name in ("results.json", "report.txt", "positions.png", "yaw.png", "lux.png"):
            assert (out / name).stat().st_size > 0, name
        docs.append(json.loads((out / "results.json").read_text()))
    a, b = docs
    assert a["n_scenes"] == 2 and a["protocol"] == "table1"
    assert _without_timing(a["scenes"]) == _without_timing(b["scenes"])
    assert a["summary"] == b["summary"] and a["breakdown"] == b["breakdown"]
    assert _without_timing(a["scenes"]) == _without_timing(serial.to_dict()["scenes"])
    assert set(a["summary"]) == set(METHODS)
    assert list(a["breakdown"]["lux"]) == ["500-1200 lx"]
    # every true book's cover kind, as truth.json has it, and the breakdown by it
    kinds = [b["cover"] for scene in a["scenes"] for b in scene["books"]]
    truth_kinds = [b["cover"] for scene in sorted((dataset / "scenes").iterdir())
                   for b in json.loads((scene / "truth.json").read_text())["books"]]
    assert kinds == truth_kinds
    closed_kinds = a["breakdown"]["cover"]["closed"]
    assert sum(c["books"] for c in closed_kinds.values()) == len(kinds)
    assert sum(c["found"] for c in closed_kinds.values()) == a["summary"]["closed"]["found"]
    assert (sum(c["within_1cm"] for c in closed_kinds.values())
            == a["summary"]["closed"]["within_1cm"])
    for scene in a["scenes"]:
        assert set(scene["methods"]) == set(METHODS)
        assert len(scene["books"]) == len(scene["methods"]["closed"]["found"])
        closed = scene["methods"]["closed"]
        n = closed["n_detections"]
        assert len(closed["quality"]) == len(closed["reprojection_error_px"]) == n
        assert all(0.0 <= q <= 1.0 for q in closed["quality"])
        assert all(0.0 <= e <= 3.0 for e in closed["reprojection_error_px"])


def test_dask_cluster_gives_the_local_results(dataset, serial):
    distributed = pytest.importorskip("distributed",
                                      reason="dask.distributed not installed (rovis[dask])")
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=1,
                                  host="127.0.0.1", protocol="tcp://",
                                  dashboard_address=None) as cluster:
        remote = ev.evaluate(dataset, METHODS, dask=cluster.scheduler_address)
    assert _without_timing(remote.scenes) == _without_timing(serial.scenes)
    assert remote.summary() == serial.summary()


def test_dask_missing_is_a_clear_error(dataset, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    assert main(["eval", str(dataset), "--dask", "tcp://127.0.0.1:1", "--methods",
                 "contour"]) == 2
    assert "pip install 'rovis[dask]'" in capsys.readouterr().err


def test_bad_scenes_are_skipped_named_and_counted(dataset, tmp_path, capsys):
    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    shutil.copytree(ds / "scenes" / "0000", ds / "scenes" / "0002")
    (ds / "scenes" / "0000" / "truth.json").write_text("{not json")
    (ds / "scenes" / "0001" / "right.png").unlink()
    assert main(["eval", str(ds), "--methods", "contour"]) == 0
    captured = capsys.readouterr()
    assert "skipped scene 0000: truth.json: unreadable" in captured.err
    assert "skipped scene 0001: right.png: image file not found" in captured.err
    assert "1 of 3 scenes scored, 2 skipped" in captured.out
    assert "2 scenes skipped" in captured.out
    doc = json.loads((dataset / "scenes" / "0000" / "truth.json").read_text())
    del doc["books"][0]["R"]
    (ds / "scenes" / "0002" / "truth.json").write_text(json.dumps(doc))
    assert main(["eval", str(ds), "--methods", "contour"]) == 2  # nothing left to score
    assert "books[0].R: missing" in capsys.readouterr().err


def test_a_method_that_raises_loses_its_books_not_the_scene(dataset, monkeypatch, capsys):
    from rovis.calib import load_calibration
    from rovis.pipeline import DetectConfig, Detector

    rig = load_calibration(dataset / "calib.yaml")

    class Broken(Detector):
        def detect(self, left, right):
            raise RuntimeError("a bug")

    class Shapes(Detector):  # a bug NumPy reports as a ValueError
        def detect(self, left, right):
            return np.zeros(3) + np.zeros(4)

    detectors = {"contour": Detector(rig, DetectConfig(method="contour")),
                 "open": Broken(rig, DetectConfig(method="open"))}
    rec = ev.score_scene(dataset / "scenes" / "0000", detectors)
    assert "skipped" not in rec
    assert "failed" not in rec["methods"]["contour"]
    assert rec["methods"]["open"]["failed"] == "RuntimeError: a bug"
    assert all(j is None for j in rec["methods"]["open"]["found"])  # its books missed
    broken = ev.summarize_method([rec], "open")
    assert broken["failed"] == 1 and broken["found"] == 0 and broken["images"] == 1
    assert broken["books"] == len(rec["books"]) > 0
    assert ev.summarize_method([rec], "contour")["failed"] == 0
    assert "failed on 1 image (books counted as missed)" in ev.method_table("open", broken, None)
    # the breakdowns count the failed images per group, only where some method failed
    table = ev.breakdown_table(ev.breakdown([rec], ["contour", "open"])["lux"], "light level")
    head, contour, broken_row = table.splitlines()
    assert head.split()[-1] == "failed"
    assert contour.split()[-1] == "0" and broken_row.split()[-1] == "1"
    assert "failed" not in ev.breakdown_table(ev.breakdown([rec], ["contour"])["lux"], "lux")
    shapes = ev.score_scene(dataset / "scenes" / "0000",
                            {"contour": detectors["contour"], "open": Shapes(rig)})
    assert shapes["methods"]["open"]["failed"].startswith("ValueError: operands could not")
    assert shapes["methods"]["contour"] == rec["methods"]["contour"]  # kept, not skipped
    # and the command names it, scoring the rest
    monkeypatch.setattr(Detector, "detect", Broken.detect)
    assert main(["eval", str(dataset), "--methods", "contour", "--limit", "1"]) == 0
    err = capsys.readouterr().err
    assert "method contour failed on scene 0000 (its books counted as missed): " \
           "RuntimeError: a bug" in err


@pytest.mark.parametrize("case", ["missing", "empty", "no-calib", "no-scenes"])
def test_not_a_dataset_is_one_line_and_exit_2(dataset, tmp_path, capsys, case):
    ds = tmp_path / "ds"
    if case != "missing":
        ds.mkdir()
    if case == "no-calib":
        shutil.copytree(dataset / "scenes", ds / "scenes")
    if case == "no-scenes":
        shutil.copy(dataset / "calib.yaml", ds)
    assert main(["eval", str(ds)]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("rovis eval: error:"), err
    want = {"missing": "no such folder", "empty": "no calib.yaml",
            "no-calib": "no calib.yaml", "no-scenes": "no scenes"}[case]
    assert want in err[0]


def test_eval_set_changes_the_detector_and_is_recorded(dataset, serial, tmp_path, capsys):
    assert serial.summary()["closed"]["found"] > 0  # the defaults find books here
    out = tmp_path / "set"
    assert main(["eval", str(dataset), "--methods", "closed", "--set", "max_cover_side=0.01",
                 "--out", str(out), "--no-plots"]) == 0
    assert "detector settings changed: max_cover_side=0.01" in capsys.readouterr().out
    doc = json.loads((out / "results.json").read_text())
    assert doc["settings"]["detector"] == ["max_cover_side=0.01"]
    assert doc["summary"]["closed"]["found"] == 0  # no cover is 1 cm long
    assert ev.Evaluation.from_dict(doc).settings == ("max_cover_side=0.01",)


def test_eval_rejects_an_unknown_setting_in_one_line(dataset, capsys):
    assert main(["eval", str(dataset), "--set", "no_such=1"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and "no_such" in err[0], err


def test_eval_rejects_unknown_methods(dataset, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["eval", str(dataset), "--methods", "closed,magic"])
    assert exc.value.code == 2
    assert "magic" in capsys.readouterr().err


# --------------------------------------------------------------------------- bench


def test_bench_pipeline_runs_small(capsys):
    assert main(["bench", "--n", "2", "--size", "512x384", "--workers", "2"]) == 0
    out = capsys.readouterr().out
    for word in ("segmentation", "undistort", "total", "closed / open", "frames/s on one core",
                 "on 2 cores", "512x384", "closed, warm", "closed, tracked"):
        assert word in out, word
    # the segmentation's own steps add up to (most of) it, for each method's column
    rows = {line.split()[0]: line for line in out.splitlines()
            if line.startswith(("  ", "segmentation  "))}
    # each cell is "median (q1-q3)", or "-" for a step a method does not run; the columns
    # are closed, open, closed warm, closed tracked
    cell = r"(\d+\.\d)\s+\(\s*[\d.]+-\s*[\d.]+\)|\s(-)(?=\s|$)"
    median = {k: [0.0 if dash else float(m) for m, dash in re.findall(cell, v)]
              for k, v in rows.items() if k != "iterations"}
    from rovis.bench import SEGMENTATION_STEPS
    for c in range(3):
        steps = sum(median[s][c] for s in SEGMENTATION_STEPS)
        assert 0.5 * median["segmentation"][c] <= steps <= 1.05 * median["segmentation"][c]
    closed, opened, warm = (float(x) for x in rows["iterations"].split()[1:4])
    assert closed > opened >= 2 and warm > opened
    assert rows["lsd"].split()[1:] == ["-"] * 4  # a step no method ran


def test_bench_pipeline_takes_detector_settings(capsys):
    assert main(["bench", "--n", "1", "--size", "512x384", "--workers", "1",
                 "--set", "segment.lsd=true"]) == 0
    lsd = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("  lsd"))
    # the columns: closed (LSD timed), open (it never runs), closed warm (timed), and
    # closed tracked (timed only in a frame where following failed)
    cells = re.findall(r"(\d+\.\d)\s+\(\s*[\d.]+-\s*[\d.]+\)|\s(-)(?=\s|$)", lsd)
    assert [bool(dash) for _, dash in cells][:3] == [False, True, False]
    assert float(cells[0][0]) > 0 and float(cells[2][0]) > 0
    assert main(["bench", "--n", "1", "--set", "segment.nope=1"]) == 2
    assert "segment.nope" in capsys.readouterr().err


def test_time_pipeline_keeps_each_frames_fastest_run(monkeypatch):
    import dataclasses
    import types

    import rovis.bench as bench
    from rovis.pipeline import Detector
    from rovis.synth.dataset import dataset_rig, dataset_scenes
    from rovis.synth.render import render

    rig = dataset_rig(0)
    (_, scene), = list(dataset_scenes("mixed", 1, 0))
    r = render(scene, 0)
    # the bench's clock: the frame's three runs take 5, 2 and 9 s
    ticks = iter([0.0, 5.0, 10.0, 12.0, 20.0, 29.0])
    monkeypatch.setattr(bench, "time", types.SimpleNamespace(perf_counter=lambda: next(ticks)))
    # each timed run's stages stamped with its number (the warm-up is run 0)
    calls = []
    detect = Detector.detect

    def stamped(self, left, right, *args, **kwargs):
        calls.append(None)
        res = detect(self, left, right, *args, **kwargs)
        return dataclasses.replace(res, timing_ms={**res.timing_ms, "split": len(calls) - 1})

    monkeypatch.setattr(Detector, "detect", stamped)
    timing = bench.time_pipeline(rig, [(r.left, r.right)], "open", repeats=3)
    assert timing.total_ms.tolist() == [2000.0]
    assert timing.stages["split"].tolist() == [2.0]  # the fastest run's stages, not another's
    with pytest.raises(ValueError, match="repeats"):
        bench.time_pipeline(rig, [(r.left, r.right)], "open", repeats=0)


def test_bench_pipeline_repeats_each_frame_and_says_so(capsys):
    assert main(["bench", "--n", "1", "--size", "512x384", "--workers", "1",
                 "--repeats", "2"]) == 0
    out = capsys.readouterr().out
    assert "each frame the fastest of 2 runs" in out
    books = next(line for line in out.splitlines() if line.startswith("books found")).split()[2:]
    assert main(["bench", "--n", "1", "--size", "512x384", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "fastest of" not in out  # one run by default, as before
    # the same books whichever run is kept
    assert next(line for line in out.splitlines()
                if line.startswith("books found")).split()[2:] == books
    with pytest.raises(SystemExit) as exc:
        main(["bench", "--n", "1", "--repeats", "0"])
    assert exc.value.code == 2
