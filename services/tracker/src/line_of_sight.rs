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
        // The vessel's own position looks east.
        assert_eq!(direction([0.0, 0.0]), ([1.0, 0.0], 0.0));
    }
}
