//! Central moments of a point set: where a fit starts (the paper's "central-moment axes").

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

/// The centroid and the covariance's eigenvectors, sorted by increasing variance: `[0]` is the
/// normal of a flat patch, `[2]` the direction of an elongated one.
pub fn principal_axes(points: &[Point3<f64>]) -> (Vector3<f64>, [Vector3<f64>; 3]) {
    let n = points.len() as f64;
    let c = points.iter().fold(Vector3::zeros(), |acc, p| acc + p.coords) / n;
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = p.coords - c;
        cov += d * d.transpose();
    }
    let eig = SymmetricEigen::new(cov / n);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    (c, order.map(|k| eig.eigenvectors.column(k).into_owned()))
}
