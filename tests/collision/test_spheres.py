"""Sphere fitting (poekin.collision.spheres): the spheres cover the shape (every sampled point
of it inside one), and reach outside it by no more than the error stated, which sampled points
of the spheres' surfaces come near; distances to the shapes here are computed in the test
(boxes, cylinders, capsules) or from SciPy's convex hull (meshes)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull, Delaunay, cKDTree

from poekin.collision.spheres import fit_spheres
from poekin.errors import InputError

VERTICES = np.random.default_rng(0).normal(size=(30, 3)) * [0.08, 0.05, 0.12]
SHAPES = [
    ("capsule", np.array([0.05, 0.2, 0.0])),
    ("cylinder", np.array([0.06, 0.15, 0.0])),
    ("cylinder", np.array([0.2, 0.02, 0.0])),  # a flat disc
    ("box", np.array([0.1, 0.04, 0.3])),
    ("mesh", VERTICES),
]
IDS = ["capsule", "cylinder", "disc", "box", "mesh"]


def _outside(kind: str, size: np.ndarray, x: np.ndarray) -> np.ndarray:
    """How far the points ``x (M, 3)`` are outside the shape (0 inside); for a mesh, the
    largest distance past a face's plane, a lower bound of it."""
    if kind == "capsule":
        z = np.clip(x[:, 2], -size[1], size[1])
        return np.maximum(np.linalg.norm(x - np.c_[0 * z, 0 * z, z], axis=1) - size[0], 0)
    if kind == "cylinder":
        radial = np.maximum(np.hypot(x[:, 0], x[:, 1]) - size[0], 0)
        return np.hypot(radial, np.maximum(np.abs(x[:, 2]) - size[1], 0))
    if kind == "box":
        return np.linalg.norm(np.maximum(np.abs(x) - size[:3], 0), axis=1)
    eq = ConvexHull(size).equations
    return np.maximum((x @ eq[:, :3].T + eq[:, 3]).max(axis=1), 0)


def _inside_samples(kind: str, size: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points of the shape: uniform in its bounding box, kept where inside, plus points
    of its surface's hardest places (the box's corners, the mesh's vertices)."""
    if kind == "mesh":
        lo, hi = size.min(axis=0), size.max(axis=0)
    else:
        e = {
            "capsule": [size[0], size[0], size[0] + size[1]],
            "cylinder": [size[0], size[0], size[1]],
        }
        hi = np.array(e.get(kind, size[:3]))
        lo = -hi
    x = rng.uniform(lo, hi, (4 * n, 3))
    if kind == "mesh":
        x = x[Delaunay(size).find_simplex(x) >= 0]
        return np.concatenate([x, size])
    x = x[_outside(kind, size, x) == 0]
    if kind == "box":
        corners = np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T * size[:3]
        x = np.concatenate([x, corners])
    if kind == "cylinder":
        t = rng.uniform(0, 2 * np.pi, n)
        rim = np.c_[size[0] * np.cos(t), size[0] * np.sin(t), size[1] * np.sign(t - np.pi)]
        x = np.concatenate([x, rim])
    return x


@pytest.mark.parametrize(("kind", "size"), SHAPES, ids=IDS)
@pytest.mark.parametrize("request_by", ["count", "tolerance"])
def test_spheres_cover_the_shape_within_the_stated_error(
    kind: str, size: np.ndarray, request_by: str
) -> None:
    rng = np.random.default_rng(1)
    args = {"count": 40} if request_by == "count" else {"tolerance": 0.03}
    fit = fit_spheres(kind, size, **args)  # type: ignore[arg-type]
    if request_by == "count":
        assert 1 <= len(fit.radii) <= 40
    else:
        assert fit.error <= 0.03
    assert np.all(fit.radii == fit.radii[0])  # one radius: the nearest centre decides
    points = _inside_samples(kind, size, 4000, rng)
    nearest, _ = cKDTree(fit.centers).query(points)
    assert np.max(nearest - fit.radii[0]) <= 1e-12  # every point inside some sphere
    # points of the spheres' surfaces: none farther outside than the error
    u = rng.normal(size=(len(fit.radii), 100, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    surface = (fit.centers[:, None] + fit.radii[:, None, None] * u).reshape(-1, 3)
    out = _outside(kind, size, surface)
    assert out.max() <= fit.error + 1e-12
    if kind != "mesh":  # the stated error is reached, nearly (not a loose bound)
        assert out.max() >= 0.7 * fit.error


def test_capsule_spheres_in_closed_form() -> None:
    fit = fit_spheres("capsule", [0.05, 0.2], count=5)
    np.testing.assert_allclose(fit.centers[:, 2], [-0.2, -0.1, 0.0, 0.1, 0.2], atol=1e-15)
    np.testing.assert_allclose(fit.radii, np.hypot(0.05, 0.05), atol=1e-15)
    assert fit.error == pytest.approx(np.hypot(0.05, 0.05) - 0.05, abs=1e-15)
    assert fit_spheres("sphere", [0.1, 0, 0], count=3).error == 0.0
    finer = fit_spheres("capsule", [0.05, 0.2], tolerance=1e-3)
    coarser = fit_spheres("capsule", [0.05, 0.2], count=len(finer.radii) - 1)
    assert finer.error <= 1e-3 < coarser.error  # the fewest within tolerance


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kind": "cone", "size": [1], "count": 3}, "unknown shape kind"),
        ({"kind": "box", "size": [1, 1, 1]}, "exactly one"),
        ({"kind": "box", "size": [1, 1, 1], "count": 2, "tolerance": 0.1}, "exactly one"),
        ({"kind": "box", "size": [1, 1, 1], "count": 0}, "count must be an integer >= 1"),
        ({"kind": "box", "size": [1, 1, 1], "tolerance": -1.0}, r"tolerance must be > 0 \(m\)"),
        ({"kind": "box", "size": [1, -1, 1], "count": 5}, "finite and > 0"),
        ({"kind": "box", "size": [1, 1], "count": 5}, "need 3 entries"),
        ({"kind": "mesh", "size": np.ones((3, 3)), "count": 5}, "V >= 4"),
        ({"kind": "box", "size": [1, 1, 1], "tolerance": 1e-6}, "coarser"),
        ({"kind": "capsule", "size": [0.1, 1], "tolerance": 1e-12}, "coarser"),
    ],
    ids=[
        "kind",
        "neither",
        "both",
        "count",
        "tolerance",
        "negative",
        "short",
        "mesh",
        "fine",
        "capsule",
    ],
)
def test_bad_input_is_one_clear_error(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message) as info:
        fit_spheres(**kwargs)  # type: ignore[arg-type]
    assert "\n" not in str(info.value)


def test_a_robots_spheres_cover_its_geoms_where_mujoco_puts_them() -> None:
    """poekin.collision.spheres on the UR5e (capsules and a cylinder): at random
    configurations, points drawn inside each collision geom where MuJoCo's FK puts it lie in
    some sphere of that geom (centres by poekin's FK), and no sphere's surface is farther from
    a capsule than the stated error."""
    import mujoco
    from helpers import load_quiet

    import poekin
    from poekin.collision import model_of
    from poekin.collision.spheres import spheres

    loaded = load_quiet("universal_robots_ur5e")
    tree = poekin.load_tree(loaded)
    found = spheres(tree, count=6)
    collision = model_of(tree)
    model = collision.mj_model
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    qpos = poekin.sample_qpos(tree, 5, seed=4, within_limits=True)
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        centers = found.world(tree, q)
        for g, kind in enumerate(collision.geom_types):
            r, h = collision.geom_sizes[g][:2]
            u = rng.uniform(-1.0, 1.0, (400, 3))
            u = u[np.linalg.norm(u[:, :2], axis=1) <= 1.0]
            local = np.column_stack([r * u[:, 0], r * u[:, 1], h * u[:, 2]])  # in the cylinder
            if kind == "capsule":  # and in its caps
                local = np.vstack([local, rng.normal(size=(200, 3))])
                local[-200:] *= (
                    r * rng.uniform(0, 1, (200, 1)) / np.linalg.norm(local[-200:], axis=1)[:, None]
                )
                local[-200:, 2] += np.where(rng.uniform(size=200) < 0.5, -h, h)
            points = local @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
            mine = found.geoms == g
            gap = np.linalg.norm(points[:, None] - centers[mine][None], axis=-1) - found.radii[mine]
            assert np.all(gap.min(axis=1) <= 1e-9), (collision.geom_names[g], gap.min(axis=1).max())
            if kind == "capsule":  # the spheres reach at most `error` out of it
                axis = data.geom_xmat[g].reshape(3, 3)[:, 2]
                for c, R in zip(centers[mine], found.radii[mine], strict=True):
                    surface = c + R * rng.normal(size=(100, 3)) / 1.0
                    surface = c + R * (surface - c) / np.linalg.norm(surface - c, axis=1)[:, None]
                    t = np.clip((surface - data.geom_xpos[g]) @ axis, -h, h)
                    near = data.geom_xpos[g] + t[:, None] * axis
                    assert np.max(np.linalg.norm(surface - near, axis=1) - r) <= found.error + 1e-9
