//! Contact detection: components of cells whose hazard is at or above a threshold (cells within
//! `link_cells` of each other in both axes are linked; 1 is 8-connectivity), with the shape features
//! the classifier uses. A boat far out gives sparse cells with gaps; linking across a gap keeps it
//! one detection instead of several that each grow a track with a junk velocity. Buffers are kept between maps (no allocation once they
//! have grown to the map size).

use messages::{GridGeometry, MapCell};

/// One connected component of hazard cells.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Detection {
    /// Hazard-weighted centroid (ENU, m).
    pub position: [f64; 2],
    /// Extent along east and north (m), cell edges included.
    pub extent: [f64; 2],
    /// Area (m^2).
    pub area: f64,
    /// Highest point above the water (m).
    pub height: f64,
    /// Ratio of the principal axes' standard deviations (>= 1; 1 = round).
    pub elongation: f64,
    /// Mean hazard probability (0..1).
    pub mean_hazard: f64,
    pub cells: u32,
}

/// What [`Detector::detect`] looks for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectParams {
    /// Cells with hazard >= this (0..=255) belong to components.
    pub threshold: u8,
    /// Smaller components are skipped (cells).
    pub min_cells: u32,
    /// At most this many components, in scan order.
    pub max: usize,
    /// Cells this close (in cells, both axes) are linked; 1 = 8-connected.
    pub link_cells: u32,
}

#[derive(Default)]
pub struct Detector {
    label: Vec<u32>,
    stack: Vec<u32>,
    pass: u32,
}

impl Detector {
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends the components of `cells` (row-major over `grid`) to `out` (cleared first), in
    /// scan order (deterministic), at most `params.max` of them.
    pub fn detect(
        &mut self,
        grid: &GridGeometry,
        cells: &[MapCell],
        params: &DetectParams,
        out: &mut Vec<Detection>,
    ) {
        let DetectParams {
            threshold,
            min_cells,
            max,
            link_cells,
        } = *params;
        let link = link_cells.max(1) as i64;
        out.clear();
        let (w, h) = (grid.width as usize, grid.height as usize);
        debug_assert_eq!(cells.len(), w * h);
        if self.label.len() != w * h {
            self.label.clear();
            self.label.resize(w * h, 0);
            self.pass = 0;
        }
        self.pass = self.pass.wrapping_add(1).max(1);
        let pass = self.pass;
        let thr = threshold.max(1);
        let r = grid.resolution_m;
        for start in 0..w * h {
            if cells[start].hazard < thr || self.label[start] == pass {
                continue;
            }
            self.stack.clear();
            self.stack.push(start as u32);
            self.label[start] = pass;
            // Hazard-weighted moments in cell units.
            let (mut n, mut sw, mut sx, mut sy, mut sxx, mut syy, mut sxy) =
                (0u32, 0f64, 0f64, 0f64, 0f64, 0f64, 0f64);
            let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
            let (mut hmax, mut hsum) = (i16::MIN, 0f64);
            while let Some(i) = self.stack.pop() {
                let i = i as usize;
                let (x, y) = (i % w, i / w);
                let c = cells[i];
                let wgt = c.hazard as f64 / 255.0;
                n += 1;
                sw += wgt;
                hsum += wgt;
                let (fx, fy) = (x as f64, y as f64);
                sx += wgt * fx;
                sy += wgt * fy;
                sxx += wgt * fx * fx;
                syy += wgt * fy * fy;
                sxy += wgt * fx * fy;
                c0 = c0.min(x);
                c1 = c1.max(x);
                r0 = r0.min(y);
                r1 = r1.max(y);
                hmax = hmax.max(c.max_height_cm);
                for dy in -link..=link {
                    for dx in -link..=link {
                        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                        if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                            continue;
                        }
                        let j = ny as usize * w + nx as usize;
                        if cells[j].hazard >= thr && self.label[j] != pass {
                            self.label[j] = pass;
                            self.stack.push(j as u32);
                        }
                    }
                }
            }
            if n < min_cells || out.len() >= max {
                continue;
            }
            let (mx, my) = (sx / sw, sy / sw);
            let vxx = (sxx / sw - mx * mx).max(0.0) + 1.0 / 12.0;
            let vyy = (syy / sw - my * my).max(0.0) + 1.0 / 12.0;
            let vxy = sxy / sw - mx * my;
            // Principal variances of the 2x2 covariance.
            let tr = vxx + vyy;
            let det = vxx * vyy - vxy * vxy;
            let disc = (tr * tr / 4.0 - det).max(0.0).sqrt();
            let (l1, l2) = (tr / 2.0 + disc, (tr / 2.0 - disc).max(1e-6));
            let west = grid.center[0] - grid.width as f64 / 2.0 * r;
            let south = grid.center[1] - grid.height as f64 / 2.0 * r;
            out.push(Detection {
                position: [west + (mx + 0.5) * r, south + (my + 0.5) * r],
                extent: [(c1 - c0 + 1) as f64 * r, (r1 - r0 + 1) as f64 * r],
                area: n as f64 * r * r,
                height: hmax.max(0) as f64 / 100.0,
                elongation: (l1 / l2).sqrt(),
                mean_hazard: hsum / n as f64,
                cells: n,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_are_8_connected_with_shape_features() {
        let grid = GridGeometry {
            width: 20,
            height: 10,
            resolution_m: 0.5,
            center: [100.0, 0.0],
        };
        let mut cells = vec![MapCell::default(); 200];
        let mut set = |x: usize, y: usize, hcm: i16| {
            cells[y * 20 + x] = MapCell {
                hazard: 255,
                max_height_cm: hcm,
                ..Default::default()
            };
        };
        // A 6x1 bar (elongated), joined diagonally to one more cell.
        for x in 2..8 {
            set(x, 2, 80);
        }
        set(8, 3, 120);
        // A separate 2x2 block.
        for (x, y) in [(14, 6), (15, 6), (14, 7), (15, 7)] {
            set(x, y, 30);
        }
        let mut d = Detector::new();
        let mut out = Vec::new();
        let params = |threshold, min_cells, max, link_cells| DetectParams {
            threshold,
            min_cells,
            max,
            link_cells,
        };
        d.detect(&grid, &cells, &params(128, 1, 16, 1), &mut out);
        assert_eq!(out.len(), 2);
        let bar = out[0];
        assert_eq!(bar.cells, 7);
        assert!((bar.area - 7.0 * 0.25).abs() < 1e-9);
        assert_eq!(bar.extent, [3.5, 1.0]);
        assert!((bar.height - 1.2).abs() < 1e-9);
        assert!(bar.elongation > 4.0, "{}", bar.elongation);
        let block = out[1];
        assert_eq!(block.cells, 4);
        assert!((block.elongation - 1.0).abs() < 1e-9);
        // Cell (14.5, 6.5) centre: west edge 95 m + 15 cells * 0.5 m, south edge -2.5 m + 7 * 0.5.
        assert!((block.position[0] - 102.5).abs() < 1e-9);
        assert!((block.position[1] - 1.0).abs() < 1e-9);
        // Below the threshold nothing is found; `max` caps the list.
        d.detect(&grid, &cells, &params(255, 5, 16, 1), &mut out);
        assert_eq!(out.len(), 1);
        d.detect(&grid, &cells, &params(1, 1, 1, 1), &mut out);
        assert_eq!(out.len(), 1);
        // Linked across the 5-cell gap between them, the bar and the block are one detection.
        d.detect(&grid, &cells, &params(1, 1, 16, 6), &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].cells, 11);
    }
}
