//! The fidelity benchmark's GMM baseline: a component of known mean and covariance, its axes
//! tilted off the coordinate axes, becomes the shell through mean +- 2 sqrt(lambda_j) v_j, in
//! memory and as read back from its map file.

use mema::bench::gmm::{GmmFit, gmm_map, gmm_shell};
use mema::io::mapfile::HostMap;
use mema_core::Entity;
use mema_core::closest_point::surface_distance;

use crate::util::Dir;

/// Rodrigues' rotation by `angle` about the unit `axis`.
fn rotation(axis: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
    let [x, y, z] = axis;
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

/// Covariance `V diag(lambda) V^T` and the eigenvectors (columns of `V`).
fn covariance(v: [[f64; 3]; 3], lambda: [f64; 3]) -> [[f64; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, value) in row.iter_mut().enumerate() {
            *value = (0..3).map(|k| v[i][k] * lambda[k] * v[j][k]).sum();
        }
    }
    c
}

fn column(v: [[f64; 3]; 3], k: usize) -> [f64; 3] {
    [v[0][k], v[1][k], v[2][k]]
}

fn along(mean: [f64; 3], dir: [f64; 3], t: f64) -> [f64; 3] {
    [0, 1, 2].map(|i| mean[i] + t * dir[i])
}

/// Every axis end of the 2-sigma ellipsoid is on the surface; half-way points are not.
fn check_axes(e: &Entity, mean: [f64; 3], v: [[f64; 3]; 3], lambda: [f64; 3]) {
    for (k, &l) in lambda.iter().enumerate() {
        let dir = column(v, k);
        let r = 2.0 * l.sqrt();
        for sign in [-1.0, 1.0] {
            let d = surface_distance(e, along(mean, dir, sign * r));
            // f32 centre and quaternion: a few 1e-7 of the longest axis.
            assert!(d < 2e-6 * (1.0 + r), "axis {k} sign {sign}: {d}");
            // Half-way out, the surface is at least half the semi-axis away (the shortest
            // semi-axis bounds it), so a shell turned the wrong way or scaled to 1 sigma fails.
            let inner = surface_distance(e, along(mean, dir, sign * 0.5 * r));
            assert!(
                inner > 0.5 * r.min(2.0 * lambda[2].sqrt()) - 1e-6,
                "axis {k}: {inner}"
            );
        }
    }
}

#[test]
fn a_tilted_component_becomes_its_two_sigma_shell() {
    let n = {
        let a: [f64; 3] = [1.0, 2.0, -0.5];
        let len = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        a.map(|x| x / len)
    };
    let v = rotation(n, 0.7);
    let mean = [0.3, -1.2, 0.7];
    // A thin tilted patch, sigma 0.2, 0.1 and 0.02; and one longer than mema's 4 m threshold,
    // which a Gaussian shell keeps finite.
    for lambda in [[0.04, 0.01, 0.0004], [100.0, 9.0, 0.25]] {
        let e = gmm_shell(mean, covariance(v, lambda)).expect("positive definite");
        assert!(!e.rotation.is_identity());
        assert_eq!(e.degenerated_axes(), 0);
        check_axes(&e, mean, v, lambda);

        // The benchmark scores the map as read back from its file.
        let fit = GmmFit {
            converged: true,
            iterations: 1,
            max_iter: 1,
            fit_s: 0.0,
            peak_rss_bytes: None,
            sklearn: None,
            scale: None,
            means: vec![mean],
            covariances: vec![covariance(v, lambda)],
            weights: vec![1.0],
        };
        let (map, dropped) = gmm_map([10.0, 20.0, 30.0], &fit).expect("consistent fit");
        assert_eq!(dropped, 0);
        let dir = Dir::new("gmm-shell");
        let path = dir.join("gmm.mema");
        map.write(&path).expect("write");
        let back = HostMap::read(&path).expect("read");
        assert_eq!(back, map);
        check_axes(&back.entities[0].entity, mean, v, lambda);
    }
}

#[test]
fn a_covariance_without_a_shell_is_dropped_not_a_panic() {
    let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert!(gmm_shell([0.0; 3], covariance(id, [1.0, 1.0, 0.0])).is_none());
    assert!(gmm_shell([0.0; 3], covariance(id, [1.0, -1.0, 1.0])).is_none());
    assert!(gmm_shell([f64::NAN, 0.0, 0.0], id).is_none());
    let mut inf = id;
    inf[0][1] = f64::INFINITY;
    assert!(gmm_shell([0.0; 3], inf).is_none());
    let fit = |covariances: Vec<[[f64; 3]; 3]>| GmmFit {
        converged: false,
        iterations: 0,
        max_iter: 0,
        fit_s: 0.0,
        peak_rss_bytes: None,
        sklearn: None,
        scale: None,
        means: vec![[0.0; 3]; 2],
        covariances,
        weights: vec![0.5; 2],
    };
    let (map, dropped) = gmm_map([0.0; 3], &fit(vec![id, inf])).expect("consistent");
    assert_eq!((map.entities.len(), dropped), (1, 1));
    assert!(gmm_map([0.0; 3], &fit(vec![id])).is_err());
}
