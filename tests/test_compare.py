"""check-suite's tolerant comparison: floating-point noise passes, a real change is named."""

import numpy as np
from matplotlib.image import imsave

from roadweaver_sumo.suite.compare import compare_files, compare_texts, same_figure

XODR = '<geometry s="0.000000000" x="15.000000000" y="{y}" hdg="1.570796327" length="{n}">\n'


def test_numbers_that_differ_in_their_last_digits_are_noise():
    a = XODR.format(y="332.448673827", n="98.181806682")
    b = XODR.format(y="332.448673829", n="98.181803950")
    same, detail = compare_texts(a, b)
    assert same and "at most 2.7e-06" in detail


def test_a_moved_point_is_drift_and_its_line_is_named():
    a = "<a/>\n" + XODR.format(y="332.448673827", n="98.181806682")
    b = "<a/>\n" + XODR.format(y="332.458673827", n="98.181806682")
    same, detail = compare_texts(a, b)
    assert not same and detail.startswith("line 2: 332.448673827 against 332.458673827")


def test_other_text_or_another_line_count_is_drift():
    assert not compare_texts('<lane id="1" type="driving"/>', '<lane id="1" type="sidewalk"/>')[0]
    assert not compare_texts("<a/>\n<b/>", "<a/>")[0]
    assert not compare_texts('<lane id="1"/>', '<lane id="2"/>')[0]


def test_latitudes_get_a_tolerance_in_degrees(tmp_path):
    for name, lat, same in (("a", "48.1409403229", True), ("b", "48.1409413230", False)):
        new, old = tmp_path / f"{name}-new.osm", tmp_path / f"{name}-old.osm"
        new.write_text(f'<node id="1" lat="{lat}" lon="11.5"/>\n')
        old.write_text('<node id="1" lat="48.1409403230" lon="11.5"/>\n')
        assert compare_files(new, old).same is same


def test_pictures_may_differ_in_a_few_pixels_only(tmp_path):
    image = np.zeros((100, 100, 3))
    imsave(tmp_path / "old.png", image)
    image[0, 0] = 1.0
    imsave(tmp_path / "speck.png", image)
    image[:20] = 1.0
    imsave(tmp_path / "changed.png", image)
    assert compare_files(tmp_path / "speck.png", tmp_path / "old.png").same
    assert not compare_files(tmp_path / "changed.png", tmp_path / "old.png").same


def test_figures_match_to_the_last_rounded_decimal():
    assert same_figure(0.123456, 0.123457) and same_figure(500, 500) and same_figure(True, True)
    assert not same_figure(0.1234, 0.1236) and not same_figure(499, 500)
    assert not same_figure(True, 1) and not same_figure(None, 0.0)
