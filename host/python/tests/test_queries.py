"""The vectorised queries against brute force in numpy over Map.entities, against `mema query`,
and transforms against `mema transform` and their own inverse."""

import numpy as np
import pytest

import mema
from conftest import cloud


@pytest.fixture(scope="module")
def bunny():
    points = mema.read_cloud(cloud("bun000.ply"))
    return points, mema.map(points, k=80, seed=4)


def query_points(points, count, seed):
    """Half near the cloud (jittered points of it), half anywhere in its box and around."""
    rng = np.random.default_rng(seed)
    lo, hi = points.min(axis=0), points.max(axis=0)
    near = points[rng.integers(len(points), size=count // 2)]
    near = near + rng.normal(scale=0.004, size=near.shape)
    far = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), size=(count - count // 2, 3))
    return np.vstack([near, far])


def local_frames(m, points):
    """Each point in each entity's frame, (P, K, 3), and the stored weights 1/r^2, (K, 3)."""
    e = m.entities
    offsets = points[:, None, :] - e.centres[None, :, :]
    # x_local = R^T (x - c)
    return np.einsum("kji,pkj->pki", e.rotations, offsets), e.weights


def surface_distances(local, weights):
    """Distance from each point to each ellipsoid's surface, (P, K): the closest point
    x_j = r_j^2 q_j / (t + r_j^2) at the root of sum_j (r_j q_j / (t + r_j^2))^2 = 1, which is
    decreasing in t on (-r_min^2, inf); found by bisection (Eberly's method)."""
    r2 = 1.0 / weights[None, :, :]  # the shells here never degenerate
    q = local

    def f(t):
        return np.sum((np.sqrt(r2) * q / (t[..., None] + r2)) ** 2, axis=-1) - 1.0

    lo = -np.min(r2, axis=-1) * np.ones(q.shape[:2])
    hi = np.sqrt(np.max(r2, axis=-1)) * np.linalg.norm(q, axis=-1) + 1e-12
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        above = f(mid) > 0
        lo = np.where(above, mid, lo)
        hi = np.where(above, hi, mid)
    t = 0.5 * (lo + hi)
    closest = r2 * q / (t[..., None] + r2)
    return np.linalg.norm(closest - q, axis=-1)


def test_occupied_is_brute_force(bunny):
    points, m = bunny
    p = query_points(points, 3000, seed=1)
    local, w = local_frames(m, p)
    level = np.sum(w * local**2, axis=-1)  # <= 1 inside
    got = m.occupied(p)
    assert got.dtype == np.int64 and got.shape == (len(p),)
    clear = np.all(np.abs(level - 1.0) > 1e-6, axis=1)  # no point on a surface to rounding
    inside = np.where(level <= 1.0, np.arange(len(m))[None, :], len(m)).min(axis=1)
    want = np.where(inside == len(m), -1, inside)
    assert np.array_equal(got[clear], want[clear])
    assert (got >= 0).sum() > 30 and (got < 0).sum() > 1000


def test_nearest_is_brute_force(bunny):
    points, m = bunny
    p = query_points(points, 1500, seed=2)
    local, w = local_frames(m, p)
    distances = surface_distances(local, w)
    inside = np.any(np.sum(w * local**2, axis=-1) <= 1.0, axis=1)
    want = np.where(inside, -1.0, 1.0) * distances.min(axis=1)
    signed, entity = m.nearest(p)
    assert signed.shape == entity.shape == (len(p),)
    assert np.allclose(signed, want, rtol=1e-5, atol=1e-7)
    # The entity named is a nearest one (ties to rounding aside).
    assert np.allclose(distances[np.arange(len(p)), entity], distances.min(axis=1), atol=1e-7)
    assert (signed < 0).sum() > 20


def ray_hits(m, origins, directions, max_range):
    """The first t in [0, max_range] where o + t d meets each entity (d normalised), or inf."""
    e = m.entities
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    o_local, w = local_frames(m, origins)
    d_local = np.einsum("kji,pj->pki", e.rotations, d)
    a = np.sum(w * d_local**2, axis=-1)
    b = 2.0 * np.sum(w * d_local * o_local, axis=-1)
    c = np.sum(w * o_local**2, axis=-1) - 1.0
    disc = b * b - 4 * a * c
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    t = np.full(a.shape, np.inf)
    for candidate in ((-b + root) / (2 * a), (-b - root) / (2 * a)):
        ok = (candidate >= 0) & (candidate <= max_range)
        t = np.where(ok & (candidate < t), candidate, t)
    return t, d


def test_ray_cast_is_brute_force(bunny):
    points, m = bunny
    rng = np.random.default_rng(3)
    origins = query_points(points, 800, seed=4)
    targets = points[rng.integers(len(points), size=len(origins))]
    directions = targets - origins  # aimed at the cloud, so most rays hit
    directions[::4] = rng.normal(size=directions[::4].shape)  # and some anywhere
    t, d = ray_hits(m, origins, directions, 0.5)
    want = t.min(axis=1)
    got_range, got_entity, got_point = m.ray_cast(origins, directions, 0.5)
    hit = np.isfinite(want)
    assert np.array_equal(np.isfinite(got_range), hit) and hit.sum() > 200
    assert np.allclose(got_range[hit], want[hit], rtol=1e-6, atol=1e-9)
    assert np.array_equal(got_entity < 0, ~hit)
    assert np.allclose(t[np.flatnonzero(hit), got_entity[hit]], want[hit], rtol=1e-6, atol=1e-9)
    assert np.allclose(got_point[hit], origins[hit] + got_range[hit, None] * d[hit], atol=1e-9)
    assert np.all(np.isnan(got_point[~hit]))
    # One origin for every ray is the same as repeating it.
    one = m.ray_cast(origins[0], directions[:50], 0.5)
    many = m.ray_cast(np.repeat(origins[:1], 50, axis=0), directions[:50], 0.5)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(one, many))


def test_one_point_queries_answer_scalars_as_mema_query(cli, bunny, tmp_path):
    points, m = bunny
    m.save(tmp_path / "bunny.mema")
    p, o, d = points[100] + 0.003, points[5] + [0.0, 0.0, 0.3], [0.01, 0.02, -1.0]
    point, ray = cli.json(
        "query", tmp_path / "bunny.mema",
        "--point", ",".join(repr(float(v)) for v in p),
        "--ray", ",".join(repr(float(v)) for v in [*o, *d]),
        "--max-range", 1.0,
    )
    signed, entity = m.nearest(p)
    assert (signed, entity) == (point["signed_distance"], point["nearest_entity"])
    occupied = m.occupied(p)
    assert (None if occupied < 0 else occupied) == point["occupied_by"]
    r, e, at = m.ray_cast(o, d, 1.0)
    assert ray["hit"] and (r, e) == (ray["range"], ray["entity"])
    assert at.tolist() == ray["point"]


def test_transform_is_the_clis_and_undoes(cli, bunny, tmp_path):
    points, m = bunny
    m.save(tmp_path / "bunny.mema")
    for angles, shift in (([0, 0, 90], [1.0, 2.0, 3.0]), ([10, 20, 30], [-0.5, 0.25, 4.0])):
        cli.run(
            "transform", tmp_path / "bunny.mema", "-o", tmp_path / "cli.mema",
            "--rotate", ",".join(map(str, angles)), "--translate", ",".join(map(str, shift)),
        )
        rotation = mema.rotation_degrees(angles)
        base = mema.load(tmp_path / "bunny.mema")
        moved = base.transform(rotation, shift)
        moved.save(tmp_path / "py.mema")
        assert (tmp_path / "py.mema").read_bytes() == (tmp_path / "cli.mema").read_bytes()
        # Queries move with the map.
        p = query_points(points, 500, seed=5)
        before, _ = base.nearest(p)
        after, _ = moved.nearest(p @ rotation.T + shift)
        assert np.allclose(before, after, atol=2e-6)
        # And the inverse brings the entities back, to f32 rounding.
        back = moved.transform(rotation.T, -rotation.T @ np.asarray(shift))
        e, b = base.entities, back.entities
        assert np.allclose(e.centres, b.centres, atol=1e-5)
        assert np.allclose(e.semi_axes, b.semi_axes, rtol=1e-6)
        assert np.array_equal(e.kinds, b.kinds)
        assert np.allclose(
            np.abs(np.einsum("kij,kij->k", e.rotations, b.rotations)), 3.0, atol=1e-5
        )


def test_a_translation_and_quarter_turns_are_exact_on_the_papers_maps(bunny):
    points, _ = bunny
    paper = mema.map(points, k=30, paper=True)
    turn = mema.rotation_degrees([90, 0, 180])
    moved = paper.transform(turn, [5.0, -3.0, 2.0])
    assert np.all(moved.entities.quaternions[:, 3] == 1.0)  # still axis-aligned
    back = moved.transform(turn.T, -turn.T @ np.array([5.0, -3.0, 2.0]))
    assert np.array_equal(back.entities.weights, paper.entities.weights)


def test_state_is_the_clis_and_free_needs_free_space(cli, tmp_path):
    """Map.state of points along one lidar sweep's rays and behind their ends equals
    `mema query --points` on the same map; points before the ends are mostly free and those
    behind mostly not; a map made without free_space calls nothing free."""
    sweep = mema.read_cloud(cloud("ouster_os1_0.pcd"))
    origins, ends = sweep.sensors
    assert len(origins) == 1
    m = mema.map(sweep, bytes=4000, free_space=True)
    assert m.report["free_space"]["images"] == 1
    rows = np.asarray(sweep)[::200]
    o = np.asarray(origins)[0]
    before, behind = o + 0.5 * (rows - o), rows + 2.0 * (rows - o) / np.linalg.norm(
        rows - o, axis=1
    )[:, None]
    points = np.vstack([before, behind])
    states = m.state(points)
    m.save(tmp_path / "sweep.mema")
    np.savetxt(tmp_path / "points.csv", points, delimiter=",", header="x,y,z", comments="")
    answers = cli.run("query", tmp_path / "sweep.mema", "--points", tmp_path / "points.csv").splitlines()
    assert answers[0] == "x,y,z,state,signed_distance,entity"
    assert [a.split(",")[3] for a in answers[1:]] == states.tolist()
    n = len(before)
    assert np.mean(states[:n] == "free") > 0.8
    assert np.mean(states[n:] == "free") < 0.1
    assert m.state(before[0]) == states[0]
    plain = mema.map(sweep, bytes=4000)
    assert not np.any(plain.state(points) == "free")


def test_free_space_where_it_is_not_kept_is_refused():
    sweep = mema.read_cloud(cloud("car6.pcd"))
    for options in ({"k": 10, "paper": True}, {"k": 10, "stream": True}, {"tolerance": 0.1}):
        with pytest.raises(mema.MemaError, match="free_space=True is kept by the shells"):
            mema.map(sweep, free_space=True, **options)
