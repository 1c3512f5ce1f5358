//! The line of sight from the own vessel: stereo measures range along it, so its errors and its
//! smear of an object lie along it, while an object's width across it stays the object's own.

/// The unit vector along `offset` (from the vessel to a point) and the offset's length; east when
/// the point is the vessel's own position.
pub fn direction(offset: [f64; 2]) -> ([f64; 2], f64) {
    let range = offset[0].hypot(offset[1]);
    if range > 1e-6 {
        ([offset[0] / range, offset[1] / range], range)
    } else {
        ([1.0, 0.0], range)
    }
}

/// The components of an offset `e` along the unit vector `u` and across it (to its left).
pub fn along_across(u: [f64; 2], e: [f64; 2]) -> (f64, f64) {
    (e[0] * u[0] + e[1] * u[1], e[1] * u[0] - e[0] * u[1])
}

/// The variances along the unit vector `u` and across it of a 2-D covariance `[xx, xy, yy]`.
pub fn along_across_variances(u: [f64; 2], [xx, xy, yy]: [f64; 3]) -> (f64, f64) {
    let [ux, uy] = u;
    (
        ux * ux * xx + 2.0 * ux * uy * xy + uy * uy * yy,
        uy * uy * xx - 2.0 * ux * uy * xy + ux * ux * yy,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spread_east_west_is_along_from_the_east_and_across_from_the_north() {
        let spread = [4.0, 0.0, 1.0];
        let (east, range) = direction([30.0, 0.0]);
        assert_eq!((east, range), ([1.0, 0.0], 30.0));
        assert_eq!(along_across_variances(east, spread), (4.0, 1.0));
        let (north, _) = direction([0.0, 20.0]);
        assert_eq!(along_across_variances(north, spread), (1.0, 4.0));
        // Seen looking north, an offset east lies across, to the right.
        assert_eq!(along_across(north, [2.0, 3.0]), (3.0, -2.0));
        // The vessel's own position looks east.
        assert_eq!(direction([0.0, 0.0]), ([1.0, 0.0], 0.0));
    }
}
