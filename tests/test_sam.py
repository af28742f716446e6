"""SAM kernel against its float64 oracle and SPy; confusion matrix and omission error."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.reference import stages as ref
from s2cl.retrieve.sam import SamClassifier, SamStatus, confusion_matrix, score_classification


def _scene(n: int, seed: int = 0):
    """Three references in 5 bands; pixels = brightness x reference + noise."""
    rng = np.random.default_rng(seed)
    refs = np.array([[0.30, 0.35, 0.40, 0.30, 0.25],
                     [0.20, 0.25, 0.30, 0.32, 0.33],
                     [0.50, 0.45, 0.40, 0.42, 0.30]])
    truth = rng.integers(0, 3, n)
    pix = refs[truth].T * rng.uniform(0.5, 1.5, n) + rng.normal(0.0, 0.01, (5, n))
    return refs, truth, pix


def test_sam_matches_oracle(rt, real_t, lanes):
    refs, _, pix = _scene(5003)
    out = SamClassifier(rt, refs, real_t=real_t, lanes=lanes).classify(pix)
    best, angle, status = ref.sam_classify(pix, refs)
    ang_all = np.sort(ref.spectral_angles(pix, refs), axis=0)
    clear = (ang_all[1] - ang_all[0]) > 1e-5  # not a near-tie
    np.testing.assert_array_equal(out.reference[clear], best[clear])
    np.testing.assert_array_equal(out.status, status)
    np.testing.assert_allclose(out.angle, angle, atol=2e-4 if real_t == "float32" else 1e-7)
    assert np.all((out.angle >= 0) & (out.angle <= np.pi))


def test_sam_matches_spy(rt):
    spectral = pytest.importorskip("spectral")
    refs, _, pix = _scene(4000, seed=3)
    spy = spectral.spectral_angles(pix.T.reshape(40, 100, 5), refs).reshape(4000, 3)
    out = SamClassifier(rt, refs, real_t="float64" if rt.has_fp64 else "float32").classify(pix)
    np.testing.assert_array_equal(out.reference, np.argmin(spy, axis=1))
    np.testing.assert_allclose(out.angle, spy.min(axis=1), atol=1e-6 if rt.has_fp64 else 2e-4)


def test_threshold_leaves_far_pixels_unclassified(rt):
    refs, _, pix = _scene(1000, seed=1)
    thr = 0.02
    out = SamClassifier(rt, refs, threshold_rad=thr).classify(pix)
    far = out.angle > thr + 1e-5
    near = out.angle < thr - 1e-5
    assert far.any() and near.any()
    assert np.all(out.status[far] == SamStatus.UNCLASSIFIED) and np.all(out.label[far] == -1)
    assert np.all(out.status[near] == SamStatus.CLASSIFIED) and np.all(out.label[near] >= 0)


def test_an_angle_equal_to_the_threshold_is_classified(rt, real_t, lanes):
    """The documented rule is angle <= threshold, ties included. With threshold 0 (cos 1, exact) a pixel
    along a reference has angle exactly 0 and the test's two sides are equal in every precision (axis-aligned
    spectra: |p|^2 and p.r are exact), so ``>=`` against ``>`` decides it; a pixel off the axes is not.
    The numpy twin says the same."""
    refs = np.eye(4)[:2]
    pix = np.array([[2.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 3.0, 0.0, 0.0], [1.0, 0.1, 0.0, 0.0]]).T
    pix = np.tile(pix, 4)  # 16 pixels: whole vectors at every lane width
    out = SamClassifier(rt, refs, threshold_rad=0.0, real_t=real_t, lanes=lanes).classify(pix)
    expected = np.tile([SamStatus.CLASSIFIED] * 3 + [SamStatus.UNCLASSIFIED], 4)
    np.testing.assert_array_equal(out.status, expected)
    np.testing.assert_array_equal(out.label[expected == SamStatus.CLASSIFIED], np.tile([0, 0, 1], 4))
    _, _, status = ref.sam_classify(pix, refs, threshold_rad=0.0)
    np.testing.assert_array_equal(status, expected)


def test_hard_cases_zero_nan_and_neighbours(rt):
    refs, _, pix = _scene(16, seed=2)
    clean = SamClassifier(rt, refs).classify(pix)
    bad = pix.copy()
    bad[:, 3] = 0.0
    bad[2, 9] = np.nan
    bad[0, 10] = np.inf
    out = SamClassifier(rt, refs).classify(bad)
    assert out.status[3] == SamStatus.ZERO_VECTOR and out.label[3] == -1 and out.angle[3] == 0.0
    assert out.status[9] == SamStatus.INVALID_INPUT and out.status[10] == SamStatus.INVALID_INPUT
    assert np.all(np.isfinite(out.angle))
    keep = np.setdiff1d(np.arange(16), [3, 9, 10])
    np.testing.assert_array_equal(out.reference[keep], clean.reference[keep])
    np.testing.assert_array_equal(out.angle[keep], clean.angle[keep])


def test_identical_references_first_wins(rt):
    refs, _, pix = _scene(500, seed=4)
    dup = np.vstack([refs, refs[1]])             # reference 3 == reference 1, but of class 2
    sam = SamClassifier(rt, dup, reference_classes=np.array([0, 1, 2, 2]))
    assert sam.duplicate_references() == [(1, 3)]
    out = sam.classify(pix)
    assert not np.any(out.reference == 3)
    np.testing.assert_array_equal(out.reference, SamClassifier(rt, refs).classify(pix).reference)


def test_reference_errors(rt):
    with pytest.raises(InputError, match="reference 1 is a zero vector"):
        SamClassifier(rt, np.array([[0.1, 0.2], [0.0, 0.0]]))
    with pytest.raises(InputError, match="threshold_rad"):
        SamClassifier(rt, np.array([[0.1, 0.2]]), threshold_rad=4.0)
    with pytest.raises(InputError, match="reference_classes"):
        SamClassifier(rt, np.array([[0.1, 0.2]]), reference_classes=np.array([-1]))
    with pytest.raises(InputError, match=r"shape \(2, n_pixels\)"):
        SamClassifier(rt, np.array([[0.1, 0.2]])).classify(np.zeros((3, 4)))


def test_confusion_and_mean_omission(rt):
    refs, truth, pix = _scene(3000, seed=5)
    out = SamClassifier(rt, refs, reference_classes=np.array([0, 1, 1])).classify(pix)
    truth2 = np.where(truth == 2, 1, truth)
    score = score_classification(truth2, out, n_classes=2)
    assert score.confusion.shape == (2, 3) and score.confusion.sum() == 3000
    assert score.mean_omission < 0.05 and score.overall_accuracy > 0.95
    cm = confusion_matrix(np.array([0, 0, 0, 1, 1]), np.array([0, 1, -1, 1, 1]), 2)
    np.testing.assert_array_equal(cm, [[1, 1, 1], [0, 2, 0]])
    from s2cl.retrieve.sam import SamResult

    r = SamResult(np.zeros(5, np.int32), np.array([0, 1, -1, 1, 1], np.int32), np.zeros(5),
                  np.array([0, 0, 1, 0, 0], np.uint8))
    s = score_classification(np.array([0, 0, 0, 1, 1]), r, 2)
    np.testing.assert_allclose(s.omission, [2 / 3, 0.0])
    assert s.mean_omission == pytest.approx(1 / 3) and s.frac_unclassified == pytest.approx(0.2)


@pytest.mark.parametrize("group", [2, 8, 64])
def test_work_group_size_changes_no_bits(rt, monkeypatch, group: int) -> None:
    """Any work-group size the device might ask for (dividing the launch or not) classifies alike; the
    outputs land in host arrays (in place on host-memory devices) that no later call overwrites."""
    refs, _, pix = _scene(1024 + 13, seed=4)
    base = SamClassifier(rt, refs).classify(pix)
    with monkeypatch.context() as m:
        m.setattr(type(rt), "work_group", lambda self, kernel: group)
        for n in (1024, 1024 + 13):
            other = SamClassifier(rt, refs).classify(pix[:, :n])
            for name in ("reference", "label", "angle", "status"):
                assert np.array_equal(getattr(other, name), getattr(base, name)[:n]), name
    again = SamClassifier(rt, refs).classify(pix[:, ::-1])  # a later call leaves earlier results alone
    assert np.array_equal(again.reference[::-1], base.reference)
    assert np.array_equal(other.reference, base.reference) and not np.shares_memory(again.reference, base.reference)
