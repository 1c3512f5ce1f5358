//! Training data and fitting for the contact classifier.
//!
//! Two sources of labelled examples:
//! - [`label_by_truth`]: detections of recorded perception world maps, labelled by the recorded
//!   simulator truth under them (what the committed model is trained on);
//! - [`rasterize`] + [`label_detections`]: simulator truth rasterized into a world-map-like grid
//!   with a noise model of what stereo sees (only the side facing the vessel, cells dropped more
//!   often with range, positions spread along the line of sight, heights under-estimated, small
//!   low wave blobs as false alarms), for scenes with no recording. The model is only as good as
//!   that noise model: in closed loop it called most boats "extended".

use crate::classify::{features, ClassModel, Model, CLASSES, FEATURES, N_FEATURES};
use crate::detect::{Detection, Detector};
use messages::{contact_class, GridGeometry, MapCell};
use nalgebra::{DMatrix, DVector};

/// An object to rasterize: contact class, ENU centre, heading, length, width, height (m).
#[derive(Debug, Clone, Copy)]
pub struct TruthShape {
    pub class: u8,
    pub position: [f64; 2],
    pub yaw: f64,
    pub size: [f64; 3],
}

/// Noise model parameters.
#[derive(Debug, Clone)]
pub struct NoiseModel {
    /// Nothing beyond this range is seen (m).
    pub max_range: f64,
    /// Probability that a visible cell is missed, at range 0 and at `max_range`.
    pub drop: [f64; 2],
    /// Along-line-of-sight position spread: sigma = a + b * range (m).
    pub spread: [f64; 2],
    /// Spurious wave blobs per map.
    pub wave_blobs: u32,
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self {
            max_range: 70.0,
            drop: [0.05, 0.45],
            spread: [0.1, 0.015],
            wave_blobs: 6,
        }
    }
}

/// Small deterministic generator (SplitMix64): examples must be reproducible bit for bit.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9e37_79b9_7f4a_7c15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn gauss(&mut self) -> f64 {
        let (u1, u2) = (self.uniform().max(1e-12), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Rasterizes `objects` and the `shore` (a land test on ENU points) around `own` into `cells`
/// over `grid`, recording in `owner` the index + 1 of the object each cell came from
/// (`objects.len() + 1` for shore, `u32::MAX` for wave blobs, 0 for none).
#[allow(clippy::too_many_arguments)]
pub fn rasterize(
    grid: &GridGeometry,
    own: [f64; 2],
    objects: &[TruthShape],
    shore: &dyn Fn(f64, f64) -> Option<f64>,
    noise: &NoiseModel,
    rng: &mut Rng,
    cells: &mut [MapCell],
    owner: &mut [u32],
) {
    cells.fill(MapCell::default());
    owner.fill(0);
    let r = grid.resolution_m;
    let mut put = |cells: &mut [MapCell], x: f64, y: f64, hazard: u8, height: f64, who: u32| {
        if let Some((c, w)) = grid.cell_of(x, y) {
            let i = (w * grid.width + c) as usize;
            let cell = &mut cells[i];
            if hazard > cell.hazard {
                cell.hazard = hazard;
                owner[i] = who;
            }
            cell.max_height_cm = cell.max_height_cm.max((height * 100.0) as i16);
            cell.observed = cell.observed.saturating_add(1);
        }
    };
    for (k, o) in objects.iter().enumerate() {
        let range = (o.position[0] - own[0]).hypot(o.position[1] - own[1]);
        if range > noise.max_range || range < 1.0 {
            continue;
        }
        let u = [
            (o.position[0] - own[0]) / range,
            (o.position[1] - own[1]) / range,
        ];
        let frac = range / noise.max_range;
        let drop = noise.drop[0] + (noise.drop[1] - noise.drop[0]) * frac;
        let sigma = noise.spread[0] + noise.spread[1] * range;
        let (s, c) = o.yaw.sin_cos();
        let (len, wid) = (o.size[0].max(r), o.size[1].max(r));
        let step = r * 0.5;
        let (na, nc) = ((len / step).ceil() as i64, (wid / step).ceil() as i64);
        for ia in 0..=na {
            for ic in 0..=nc {
                let a = -len / 2.0 + len * ia as f64 / na.max(1) as f64;
                let b = -wid / 2.0 + wid * ic as f64 / nc.max(1) as f64;
                let (dx, dy) = (a * c - b * s, a * s + b * c);
                // Only the side facing the vessel reflects range points.
                if dx * u[0] + dy * u[1] > 0.25 * (len.min(wid)) + r {
                    continue;
                }
                if rng.uniform() < drop {
                    continue;
                }
                let e = rng.gauss() * sigma;
                let hazard = (255.0 * (0.6 + 0.4 * rng.uniform())) as u8;
                let height = o.size[2] * (0.7 + 0.3 * rng.uniform());
                put(
                    cells,
                    o.position[0] + dx + e * u[0],
                    o.position[1] + dy + e * u[1],
                    hazard,
                    height,
                    k as u32 + 1,
                );
            }
        }
    }
    // Shore: land cells facing the vessel within range, as a band a few metres deep.
    let shore_id = objects.len() as u32 + 1;
    for row in 0..grid.height {
        for col in 0..grid.width {
            let [x, y] = grid.cell_center(col, row);
            let range = (x - own[0]).hypot(y - own[1]);
            if range > noise.max_range || range < 1.0 {
                continue;
            }
            let Some(h) = shore(x, y) else { continue };
            // Visible if the point a few metres closer along the line of sight is water.
            let back = 4.0 / range;
            if shore(x - (x - own[0]) * back, y - (y - own[1]) * back).is_some() {
                continue;
            }
            let drop = noise.drop[0] + (noise.drop[1] - noise.drop[0]) * range / noise.max_range;
            if rng.uniform() < drop {
                continue;
            }
            let hazard = (255.0 * (0.6 + 0.4 * rng.uniform())) as u8;
            put(
                cells,
                x,
                y,
                hazard,
                h * (0.7 + 0.3 * rng.uniform()),
                shore_id,
            );
        }
    }
    // Wave blobs: 1 to 5 cells, low, moderate hazard, anywhere in range.
    for _ in 0..noise.wave_blobs {
        let ang = rng.uniform() * std::f64::consts::TAU;
        let range = 5.0 + rng.uniform() * (noise.max_range - 5.0);
        let (x, y) = (own[0] + range * ang.cos(), own[1] + range * ang.sin());
        if shore(x, y).is_some() {
            continue;
        }
        let n = 1 + (rng.uniform() * 5.0) as u32;
        let height = 0.1 + 0.5 * rng.uniform();
        let hazard = (130.0 + 90.0 * rng.uniform()) as u8;
        let (mut px, mut py) = (x, y);
        for _ in 0..n {
            put(cells, px, py, hazard, height, u32::MAX);
            px += (rng.uniform() - 0.5) * 2.0 * r;
            py += (rng.uniform() - 0.5) * 2.0 * r;
        }
    }
}

/// Labels each detection by the source owning most of its cells: the class of that object,
/// EXTENDED for shore, FALSE_ALARM for wave blobs.
pub fn label_detections(
    grid: &GridGeometry,
    cells: &[MapCell],
    owner: &[u32],
    objects: &[TruthShape],
    detector: &mut Detector,
    threshold: u8,
    out: &mut Vec<(Detection, u8)>,
) {
    let mut dets = Vec::new();
    let params = crate::detect::DetectParams {
        threshold,
        min_cells: 1,
        max: 4096,
        link_cells: 1,
        split_min_cells: u32::MAX,
        los_link: None,
    };
    detector.detect(grid, cells, &params, &mut dets);
    // Majority owner per detection: the owner of the cells nearest its centroid and extent box.
    for d in dets {
        let mut votes: Vec<(u32, u32)> = Vec::new();
        let r = grid.resolution_m;
        let (hx, hy) = (d.extent[0] / 2.0 + r, d.extent[1] / 2.0 + r);
        let mut y = d.position[1] - hy;
        while y <= d.position[1] + hy {
            let mut x = d.position[0] - hx;
            while x <= d.position[0] + hx {
                if let Some((c, w)) = grid.cell_of(x, y) {
                    let i = (w * grid.width + c) as usize;
                    if cells[i].hazard >= threshold && owner[i] != 0 {
                        match votes.iter_mut().find(|v| v.0 == owner[i]) {
                            Some(v) => v.1 += 1,
                            None => votes.push((owner[i], 1)),
                        }
                    }
                }
                x += r;
            }
            y += r;
        }
        votes.sort_by_key(|v| (std::cmp::Reverse(v.1), v.0));
        let Some(&(who, _)) = votes.first() else {
            continue;
        };
        let class = if who == u32::MAX {
            contact_class::FALSE_ALARM
        } else if who as usize > objects.len() {
            contact_class::EXTENDED
        } else {
            objects[who as usize - 1].class
        };
        out.push((d, class));
    }
}

/// How far outside an object's footprint a detection still belongs to it (m): stereo spreads an
/// object along the line of sight, and the INS error moves the whole map.
pub const TRUTH_MARGIN_M: f64 = 2.5;

/// Labels detections of a perception world map by the truth around them: the class of the object
/// whose footprint (grown by [`TRUTH_MARGIN_M`]) holds the detection's centroid (the nearest centre
/// if several do), EXTENDED where `is_land` says the centroid or a point of its extent box is
/// shore, FALSE_ALARM otherwise. `map_offset` is where the map puts a point minus where it is
/// (the INS error); detection positions are moved back by it before the test.
pub fn label_by_truth(
    detections: &[Detection],
    objects: &[TruthShape],
    map_offset: [f64; 2],
    is_land: &dyn Fn(f64, f64) -> bool,
    out: &mut Vec<(Detection, u8)>,
) {
    for d in detections {
        let p = [d.position[0] - map_offset[0], d.position[1] - map_offset[1]];
        let inside = |o: &TruthShape| {
            let (dx, dy) = (p[0] - o.position[0], p[1] - o.position[1]);
            let (s, c) = o.yaw.sin_cos();
            let along = dx * c + dy * s;
            let across = -dx * s + dy * c;
            along.abs() <= o.size[0] / 2.0 + TRUTH_MARGIN_M
                && across.abs() <= o.size[1] / 2.0 + TRUTH_MARGIN_M
        };
        let dist = |o: &TruthShape| (p[0] - o.position[0]).hypot(p[1] - o.position[1]);
        let owner = objects
            .iter()
            .filter(|o| inside(o))
            .min_by(|a, b| dist(a).total_cmp(&dist(b)));
        let (hx, hy) = (d.extent[0] / 2.0, d.extent[1] / 2.0);
        let land = [(0.0, 0.0), (-hx, -hy), (hx, -hy), (-hx, hy), (hx, hy)]
            .iter()
            .any(|(ox, oy)| is_land(p[0] + ox, p[1] + oy));
        let class = match owner {
            Some(o) => o.class,
            None if land => contact_class::EXTENDED,
            None => contact_class::FALSE_ALARM,
        };
        out.push((*d, class));
    }
}

/// How [`fit`] shapes the model beyond the data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// The covariances between features are scaled by `1 - shrink` (regularised discriminant
    /// analysis: 0 keeps them, 1 leaves the variances alone, naive Bayes).
    pub shrink: f64,
    /// A false alarm's prior over each object class's: the object classes share equal priors (the
    /// class mix of training maps says little about the mix at sea), and a weight above 1 makes an
    /// ambiguous detection a false alarm rather than an object the sequencer avoids or follows.
    pub false_alarm_weight: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            shrink: 0.0,
            false_alarm_weight: 1.0,
        }
    }
}

/// Fits one Gaussian per class.
pub fn fit(
    samples: &[(Detection, u8)],
    options: FitOptions,
    provenance: String,
) -> Result<Model, String> {
    let weight = |class: u8| {
        if class == contact_class::FALSE_ALARM {
            options.false_alarm_weight.max(1e-3)
        } else {
            1.0
        }
    };
    let total: f64 = CLASSES.iter().map(|&c| weight(c)).sum();
    let mut classes = Vec::new();
    for class in CLASSES {
        let xs: Vec<[f64; N_FEATURES]> = samples
            .iter()
            .filter(|s| s.1 == class)
            .map(|s| features(&s.0))
            .collect();
        if xs.len() < 5 * N_FEATURES {
            return Err(format!(
                "only {} examples of class {}",
                xs.len(),
                contact_class::name(class)
            ));
        }
        let (mean, mut cov) = mean_and_cov(&xs, 1e-3);
        for (k, c) in cov.iter_mut().enumerate() {
            if k / N_FEATURES != k % N_FEATURES {
                *c *= 1.0 - options.shrink.clamp(0.0, 1.0);
            }
        }
        classes.push(ClassModel::new(class, weight(class) / total, mean, cov));
    }
    let mut model = Model {
        version: Model::VERSION,
        features: FEATURES.iter().map(|s| s.to_string()).collect(),
        classes,
        provenance,
    };
    model.prepare()?;
    Ok(model)
}

/// The mean and covariance of samples of the features (row by row), each variance at least
/// `min_var` so a class with few samples does not become spiky.
fn mean_and_cov(xs: &[[f64; N_FEATURES]], min_var: f64) -> (Vec<f64>, Vec<f64>) {
    let n = xs.len().max(1) as f64;
    let mean = DVector::from_fn(N_FEATURES, |j, _| xs.iter().map(|x| x[j]).sum::<f64>() / n);
    let mut cov = DMatrix::zeros(N_FEATURES, N_FEATURES);
    for x in xs {
        let d = DVector::from_column_slice(x) - &mean;
        cov += &d * d.transpose() / n;
    }
    for j in 0..N_FEATURES {
        cov[(j, j)] = cov[(j, j)].max(min_var);
    }
    (
        mean.iter().copied().collect(),
        cov.transpose().iter().copied().collect(),
    )
}

/// Per-class accuracy (recall) on `samples`: (class, correct, total).
pub fn accuracy(model: &Model, samples: &[(Detection, u8)]) -> Vec<(u8, u32, u32)> {
    CLASSES
        .iter()
        .map(|&class| {
            let mut ok = 0;
            let mut n = 0;
            for (d, c) in samples.iter().filter(|s| s.1 == class) {
                n += 1;
                ok += (model.classify(d).0 == *c) as u32;
            }
            (class, ok, n)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn detection(position: [f64; 2]) -> Detection {
        Detection {
            position,
            extent: [2.0, 2.0],
            area: 4.0,
            height: 1.0,
            elongation: 1.0,
            mean_hazard: 0.8,
            peak_hazard: 230,
            cells: 16,
            ..Default::default()
        }
    }

    #[test]
    fn fit_weighs_false_alarms_and_shrinks_the_covariances() {
        // 40 detections per class whose area and height grow together.
        let samples: Vec<(Detection, u8)> = CLASSES
            .iter()
            .enumerate()
            .flat_map(|(k, &class)| {
                (0..40).map(move |i| {
                    let x = 1.0 + k as f64 + 0.05 * i as f64;
                    let d = Detection {
                        area: x.exp(),
                        height: x + 0.01 * (i % 3) as f64,
                        elongation: 1.0 + 0.1 * (i % 5) as f64,
                        extent: [1.0 + 0.1 * (i % 7) as f64, 1.0],
                        mean_hazard: 0.5 + 0.01 * (i % 4) as f64,
                        along_sd_m: 0.5 + 0.02 * (i % 6) as f64,
                        across_sd_m: 0.4 + 0.03 * (i % 2) as f64,
                        ..Default::default()
                    };
                    (d, class)
                })
            })
            .collect();
        let options = FitOptions {
            shrink: 0.0,
            false_alarm_weight: 2.0,
        };
        let m = fit(&samples, options, String::new()).unwrap();
        for c in &m.classes {
            let expected = if c.class == contact_class::FALSE_ALARM {
                0.4
            } else {
                0.2
            };
            assert!((c.prior - expected).abs() < 1e-12, "{} {}", c.name, c.prior);
        }
        // ln(area) and height move together: a covariance between them, kept unshrunk ...
        let n = FEATURES.len();
        assert!(m.classes[0].cov[1] > 0.5 * m.classes[0].cov[0]);
        // ... and gone at shrink 1 (naive Bayes), the variances the same.
        let naive = fit(
            &samples,
            FitOptions {
                shrink: 1.0,
                ..options
            },
            String::new(),
        )
        .unwrap();
        assert_eq!(naive.classes[0].cov[1], 0.0);
        assert_eq!(naive.classes[0].cov[n + 1], m.classes[0].cov[n + 1]);
        // Too few examples of a class is an error, not a model.
        assert!(fit(&samples[..60], options, String::new()).is_err());
    }

    #[test]
    fn perception_detections_are_labelled_by_the_truth_they_lie_on() {
        // A 9 m boat heading north at (0, 50), a buoy at (10, 50), shore west of x = -40.
        let objects = [
            TruthShape {
                class: contact_class::BOAT,
                position: [0.0, 50.0],
                yaw: std::f64::consts::FRAC_PI_2,
                size: [9.0, 3.0, 2.0],
            },
            TruthShape {
                class: contact_class::CHANNEL_MARKER,
                position: [10.0, 50.0],
                yaw: 0.0,
                size: [1.0, 1.0, 1.5],
            },
        ];
        let land = |x: f64, _y: f64| x < -40.0;
        // The map is 1 m east of the truth (INS error).
        let offset = [1.0, 0.0];
        let dets = [
            detection([1.5, 54.0]),  // on the boat's bow: boat
            detection([3.5, 54.0]),  // 2.5 m abreast of the boat, under the margin: boat
            detection([10.5, 50.0]), // the buoy
            detection([-40.5, 0.0]), // shore under its extent box
            detection([30.0, 20.0]), // open water: false alarm
            detection([1.0, 62.0]),  // 7.5 m past the bow: false alarm
        ];
        let mut out = Vec::new();
        label_by_truth(&dets, &objects, offset, &land, &mut out);
        let classes: Vec<u8> = out.iter().map(|(_, c)| *c).collect();
        assert_eq!(
            classes,
            [
                contact_class::BOAT,
                contact_class::BOAT,
                contact_class::CHANNEL_MARKER,
                contact_class::EXTENDED,
                contact_class::FALSE_ALARM,
                contact_class::FALSE_ALARM,
            ]
        );
    }
}
