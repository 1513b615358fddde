import numpy as np
from pdeface.surface.fit import grid_faces
from pdeface.surface.report import PIT_DEPTH_MM, _in_pit, weighted_percentile

AXIS_Z = -100.0


def cylinder_sheet(radius):
    """A sheet r = radius(theta, y) round the vertical axis at z = AXIS_Z, 0.25 mm cells."""
    th = np.linspace(-0.3, 0.3, int(0.6 * 100 / 0.25) + 1)
    y = np.linspace(-15, 15, 121)
    TH, Y = np.meshgrid(th, y, indexing="ij")
    R = radius(TH, Y)
    V = np.stack([R * np.sin(TH), Y, AXIS_Z + R * np.cos(TH)], axis=-1).reshape(-1, 3)
    Q = grid_faces(len(th), len(y))
    return V, np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])


def test_a_narrow_deep_hole_is_a_pit_and_a_broad_hollow_is_not():
    # A 3 mm wide hole 8 mm deep (a flared nostril seen head on) beside a 12 mm wide, 3 mm deep hollow.
    def radius(th, y):
        hole = (np.abs(100 * (th + 0.1)) < 1.5) & (np.abs(y) < 1.5)
        hollow = 3.0 * np.exp(-((100 * (th - 0.1)) ** 2 + y ** 2) / 18.0)
        return 100.0 - np.where(hole, 8.0, 0.0) - hollow
    V, T = cylinder_sheet(radius)
    th = np.array([-0.1, 0.1, 0.0, -0.1])
    y = np.array([0.0, 0.0, 0.0, 8.0])
    r = radius(th, y)
    assert r[0] < 100 - PIT_DEPTH_MM and r[1] < 98
    assert _in_pit(V, T, AXIS_Z, th, y, r).tolist() == [True, False, False, False]


def test_weighted_percentile_counts_each_value_by_its_weight():
    x = np.arange(100.0)
    assert weighted_percentile(x, np.ones(100), 95) == 94.0
    w = np.ones(100)
    w[:10] = 100.0  # the ten smallest values hold 1000 of 1090 units of weight
    assert weighted_percentile(x, w, 50) < 10 and weighted_percentile(x, w, 95) > 40
    assert weighted_percentile(x[::-1], w[::-1], 50) == weighted_percentile(x, w, 50)
