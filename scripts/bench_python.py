"""The Python route to the same map, for `mema bench --python` (benchmark 4).

What a researcher would write with the usual tools: numpy to hold the cloud, scikit-learn's
KMeans (k-means++ seeding, Lloyd, the same tolerance rule and iteration cap as mema), and a
numpy DE/rand/1/bin over eq. 12 evaluated directly over each cluster's points, vectorised over
the population: the paper's population 10, 50 generations, F = 1.2, CR = 0.7, the semi-axes
searched in ln r within [0.05 s, threshold] as mema's default box. Every cluster gets an
ellipsoid fit and a one-radius sphere fit, as `mema map` does.

Input: an .npy of float32 points (n x 3) written by `mema bench`. Output: one JSON line of
timings in seconds.
"""

import argparse
import json
import math
import time

import numpy as np
from sklearn.cluster import KMeans

POPULATION = 10
GENERATIONS = 50
MUTATION = 1.2
CROSSOVER = 0.7
ALPHA = 0.8
THRESHOLD = 4.0
LOWER = 0.05


def fitness(centred, n, radii):
    """Eq. 12 for a population of semi-axes (P x 3) over a cluster's centred points (m x 3)."""
    s = (centred * centred) @ (1.0 / (radii * radii)).T
    g = 0.5 * (1.0 - s)
    rms = np.sqrt(np.mean(g * g, axis=0))
    volume = 4.0 / 3.0 * math.pi * np.prod(radii, axis=1) / n
    return ALPHA * rms + (1.0 - ALPHA) * volume


def de(centred, dims, rng):
    n = centred.shape[0]
    spread = math.sqrt(float(np.mean(np.sum(centred * centred, axis=1)))) or 1e-6
    lo, hi = math.log(LOWER * spread), math.log(THRESHOLD)
    hi = max(hi, lo)

    def score(x):
        r = np.exp(x)
        if dims == 1:
            r = np.repeat(r, 3, axis=1)
        return fitness(centred, n, r)

    pop = rng.uniform(lo, hi, (POPULATION, dims))
    scores = score(pop)
    others = np.array([[j for j in range(POPULATION) if j != i] for i in range(POPULATION)])
    for _ in range(GENERATIONS):
        picks = np.array([rng.choice(others[i], 3, replace=False) for i in range(POPULATION)])
        donors = pop[picks[:, 0]] + MUTATION * (pop[picks[:, 1]] - pop[picks[:, 2]])
        donors = np.clip(donors, lo, hi)
        cross = rng.random((POPULATION, dims)) <= CROSSOVER
        cross[np.arange(POPULATION), rng.integers(0, dims, POPULATION)] = True
        trial = np.where(cross, donors, pop)
        trial_scores = score(trial)
        better = trial_scores <= scores
        pop[better] = trial[better]
        scores[better] = trial_scores[better]
    return np.exp(pop[np.argmin(scores)])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("points")
    parser.add_argument("k", type=int)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    t0 = time.perf_counter()
    points = np.load(args.points)
    t1 = time.perf_counter()
    km = KMeans(
        n_clusters=args.k,
        init="k-means++",
        n_init=1,
        max_iter=100,
        tol=1e-4,
        algorithm="lloyd",
        random_state=args.seed,
    ).fit(points)
    t2 = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    order = np.argsort(km.labels_, kind="stable")
    bounds = np.cumsum(np.bincount(km.labels_, minlength=args.k))[:-1]
    fitted = 0
    for members in np.split(order, bounds):
        if members.size == 0:
            continue
        cluster = points[members].astype(np.float64)
        centred = cluster - cluster.mean(axis=0)
        de(centred, 3, rng)
        de(centred, 1, rng)
        fitted += 1
    t3 = time.perf_counter()
    print(
        json.dumps(
            {
                "read_s": t1 - t0,
                "kmeans_s": t2 - t1,
                "fit_s": t3 - t2,
                "total_s": t3 - t0,
                "iterations": int(km.n_iter_),
                "clusters_fitted": fitted,
            }
        )
    )


if __name__ == "__main__":
    main()
