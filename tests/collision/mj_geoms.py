"""MuJoCo's own distances for the collision tests: a model of two mocap bodies, one geom each,
posed and sized at will, and ``mj_geomDistance`` between them (the reference every closed form
and the GJK are checked against)."""

from __future__ import annotations

import mujoco
import numpy as np

KINDS = ("plane", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh")
DISTMAX = 100.0  # mj_geomDistance's cap; every pair drawn here is nearer


class GeomPair:
    """Two geoms of kinds ``kind1`` and ``kind2`` on mocap bodies; a mesh's vertices are given
    at construction (MuJoCo takes their convex hull, in the frame it moves the mesh to)."""

    def __init__(self, kind1: str, kind2: str, vertices: np.ndarray | None = None) -> None:
        assets = ""
        if "mesh" in (kind1, kind2):
            assert vertices is not None
            verts = " ".join(f"{v:.17g}" for v in np.asarray(vertices).ravel())
            assets = f'<asset><mesh name="m" vertex="{verts}"/></asset>'

        def geom(kind: str, name: str) -> str:
            extra = ' mesh="m"' if kind == "mesh" else ' size="0.1 0.1 0.1"'
            return f'<geom name="{name}" type="{kind}"{extra}/>'

        xml = f"""<mujoco>{assets}<worldbody>
          <body name="b1" mocap="true">{geom(kind1, "g1")}</body>
          <body name="b2" mocap="true">{geom(kind2, "g2")}</body>
        </worldbody></mujoco>"""
        self.kinds = (kind1, kind2)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)

    def set(self, poses: tuple[np.ndarray, np.ndarray], sizes: tuple[np.ndarray, ...]) -> None:
        """Both geoms at ``poses`` (4x4, world) with MuJoCo ``sizes`` (ignored for a mesh)."""
        m, d = self.model, self.data
        for g, (T, size) in enumerate(zip(poses, sizes, strict=True)):
            d.mocap_pos[g] = T[:3, 3]
            mujoco.mju_mat2Quat(d.mocap_quat[g], np.ascontiguousarray(T[:3, :3]).ravel())
            if self.kinds[g] != "mesh":
                m.geom_size[g, : len(size)] = size
                m.geom_rbound[g] = 0.0 if self.kinds[g] == "plane" else 10.0
        mujoco.mj_kinematics(m, d)

    def distance(self) -> tuple[float, np.ndarray]:
        """``mj_geomDistance`` from geom 1 to geom 2, and its witness points ``(2, 3)``."""
        fromto = np.zeros(6)
        dist = mujoco.mj_geomDistance(self.model, self.data, 0, 1, DISTMAX, fromto)
        return float(dist), fromto.reshape(2, 3)

    def mesh_world_vertices(self, g: int) -> np.ndarray:
        """The mesh of geom ``g``'s vertices in the world, as MuJoCo placed them."""
        m, d = self.model, self.data
        adr, n = m.mesh_vertadr[0], m.mesh_vertnum[0]
        local = m.mesh_vert[adr : adr + n]
        return local @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]


def random_poses(
    rng: np.random.Generator, shape: tuple[int, ...], spread: float = 0.3
) -> np.ndarray:
    """Poses ``shape + (4, 4)``: uniform rotations (unit quaternions through MuJoCo), positions
    uniform in a cube of half side ``spread``."""
    n = int(np.prod(shape))
    quats = rng.normal(size=(n, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    T = np.tile(np.eye(4), (n, 1, 1))
    for k in range(n):
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, quats[k])
        T[k, :3, :3] = R.reshape(3, 3)
    T[:, :3, 3] = rng.uniform(-spread, spread, (n, 3))
    return T.reshape(*shape, 4, 4)


def random_sizes(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """MuJoCo sizes ``shape + (3,)``, each in [0.02, 0.2] m."""
    return rng.uniform(0.02, 0.2, (*shape, 3))


def mj_distances(
    kind1: str,
    T1: np.ndarray,
    S1: np.ndarray,
    kind2: str,
    T2: np.ndarray,
    S2: np.ndarray,
    vertices: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``mj_geomDistance`` for every pair of a batch (poses ``(..., 4, 4)``, sizes ``(..., 3)``,
    broadcast together): distances ``(...)`` and witness points ``(..., 2, 3)``."""
    shape = np.broadcast_shapes(T1.shape[:-2], T2.shape[:-2], S1.shape[:-1], S2.shape[:-1])
    pair = GeomPair(kind1, kind2, vertices)
    T1, T2 = np.broadcast_to(T1, (*shape, 4, 4)), np.broadcast_to(T2, (*shape, 4, 4))
    S1, S2 = np.broadcast_to(S1, (*shape, 3)), np.broadcast_to(S2, (*shape, 3))
    dist, points = np.zeros(shape), np.zeros((*shape, 2, 3))
    for k in np.ndindex(shape):
        pair.set((T1[k], T2[k]), (S1[k], S2[k]))
        dist[k], points[k] = pair.distance()
    return dist, points
