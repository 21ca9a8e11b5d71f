"""The Gaussian-mixture baseline of `mema bench --only fidelity`.

A full-covariance GMM is what a robotics engineer would otherwise store at a byte budget (the
issue counts 40 bytes a component: mean 3 + covariance 6 + weight 1, as f32). It is fitted with
scikit-learn's defaults but for the settings the issue names: k-means initialisation, seed 0
and an iteration cap high enough that EM stops on its own tolerance, so the baseline is a
converged one; whether it did is reported, not assumed.

Input: an .npy of float32 points (n x 3) written by `mema bench`, in the cloud's local frame.
Output: one JSON object on stdout: means, covariances, weights, whether EM converged, its
iterations, and the seconds it took.
"""

import argparse
import json
import resource
import time

import numpy as np
import sklearn
from sklearn.mixture import GaussianMixture


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("points")
    parser.add_argument("components", type=int)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-iter", type=int, default=2000)
    args = parser.parse_args()

    t0 = time.perf_counter()
    # float64: scikit-learn would keep float32 input in float32, and there the Cholesky
    # factor of a thin component's covariance fails outright (seen at 960 components) where
    # float64 fits. It costs memory: about 12 GB at the peak for 250k points and 960
    # components (the n x k responsibilities and their temporaries).
    points = np.load(args.points).astype(np.float64)
    # scikit-learn adds reg_covar = 1e-6 to every covariance's diagonal, in the data's units:
    # on a bunny scan in metres that is a 1 mm standard deviation floor, twice the point
    # spacing, and every thin component comes out fat (seen: smallest eigenvalues pinned at
    # 1e-6). Fitting in units of the cloud's RMS spread makes the floor 1e-6 of the cloud's
    # size whatever its unit, as a user who standardises first would have it; the means and
    # covariances are scaled back.
    centre = points.mean(axis=0)
    scale = float(np.sqrt(((points - centre) ** 2).sum(axis=1).mean())) or 1.0
    points = (points - centre) / scale
    t1 = time.perf_counter()
    gmm = GaussianMixture(
        n_components=args.components,
        covariance_type="full",
        init_params="kmeans",
        random_state=args.seed,
        max_iter=args.max_iter,
    ).fit(points)
    t2 = time.perf_counter()
    print(
        json.dumps(
            {
                "components": args.components,
                "sklearn": sklearn.__version__,
                "dtype": str(points.dtype),
                "converged": bool(gmm.converged_),
                "iterations": int(gmm.n_iter_),
                "max_iter": args.max_iter,
                "lower_bound": float(gmm.lower_bound_),
                "read_s": t1 - t0,
                "fit_s": t2 - t1,
                # Linux reports kilobytes.
                "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                "scale": scale,
                "means": (gmm.means_ * scale + centre).tolist(),
                "covariances": (gmm.covariances_ * scale * scale).tolist(),
                "weights": gmm.weights_.tolist(),
            }
        )
    )


if __name__ == "__main__":
    main()
