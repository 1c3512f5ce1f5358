//! Contact detection: components of cells whose hazard is at or above a threshold (cells within
//! `link_cells` of each other in both axes are linked; 1 is 8-connectivity), with the shape features
//! the classifier uses. A boat far out gives sparse cells with gaps; linking across a gap keeps it
//! one detection instead of several that each grow a track with a junk velocity.
//!
//! Guided detection: the world map confirms a cell only after several frames of evidence, so a boat
//! that moves its own length in that time maps as a sliver. Where the tracker expects a confirmed
//! track ([`Detector::guide`]), cells join components from a lower hazard, so the evidence of the
//! last frames, spread along the boat's path, still forms one detection. Elsewhere the threshold,
//! and so the rejection of one-frame stereo noise, is unchanged. Buffers are kept between maps (no
//! allocation once they have grown to the map size).
//!
//! A boat seen from astern at speed moves a few cells per frame, so even its newest cells carry
//! one observation in the average of several and can stay below the guided threshold. Inside a
//! window a cell therefore also joins from a lower hazard when its latest observation stood well
//! above the water ([`GuideThresholds::lifted_height_cm`]): wave glint and wave crests lie flat,
//! a hull and a cabin do not.
//!
//! Seen from astern at 15-20 m the transom of a boat making 7 m/s stands in new cells every frame,
//! and perception, whose temporal filter is anchored to the world, gives a first sighting little
//! hazard: its cells held 20-40 of 255 under 75-140 points 2 m high (follow_boat, seed 42, 248 s),
//! while the smear of earlier frames astern held 60-120. Inside a window that asks for it
//! ([`GuideWindow::fresh`], with [`GuideThresholds::fresh_min_points`] set, as the tracker does by
//! default) a cell observed in this very map by a few points standing that high therefore
//! joins at any hazard, and the component also reports the centroid of such cells
//! ([`Detection::fresh_position`]): where the hull is now.
//!
//! Linking also joins a boat moored by a bank to the bank, through the bank's range smear. A
//! component larger than any boat ([`DetectParams::split_min_cells`]) is therefore cut at its dense
//! parts: each compact one is a detection of its own, the rest one more. Not where a boat-sized
//! track's guide window reaches in ([`GuideWindow::keep_whole`]): a moving boat and its smear.

use crate::line_of_sight;
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
    /// Hazard-weighted standard deviation of the cells along and across the line of sight from
    /// the map's centre (m): stereo smears an object in range, by metres at 100 m, while its width
    /// across the line of sight stays what the object's is.
    pub along_sd_m: f64,
    pub across_sd_m: f64,
    /// Highest cell hazard (0..=255); below the detection threshold the component exists only
    /// through a guide window.
    pub peak_hazard: u8,
    pub cells: u32,
    /// Cells of a guide window observed in this very map standing at least the window's lifted
    /// height above the water (see [`Detector::guide`]), and their centroid (ENU, m): where the
    /// object's surface is now, while the hazard-weighted centroid also weighs the older frames the
    /// map still averages (for a moving boat, the smear astern of it). Outside guide windows 0
    /// cells, and the position is `position`.
    pub fresh_cells: u32,
    pub fresh_position: [f64; 2],
    /// Cells at the detection threshold that were observed in this very map: evidence of now,
    /// while a cell the map holds from older observations alone may be a mismatch frames old.
    pub observed_cells: u32,
    /// A component larger than any boat, or a dense part cut from one (see
    /// [`DetectParams::split_min_cells`]): a bank, or a boat moored along it. Neither moves: a
    /// track it places is held still.
    pub in_large_component: bool,
}

/// What a cell inside a guide window needs to join a component (see [`Detector::guide`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuideThresholds {
    /// Any cell with hazard >= this (0..=255).
    pub hazard: u8,
    /// A cell whose latest observation stood at least `lifted_height_cm` above the water, from
    /// hazard >= this.
    pub lifted_hazard: u8,
    pub lifted_height_cm: i16,
    /// A cell observed in this very map by at least this many points, its highest
    /// `lifted_height_cm` or more above the water, joins at any hazard and counts toward
    /// [`Detection::fresh_position`]; 0 turns that off.
    pub fresh_min_points: u8,
}

/// A disc of the map around a track's predicted position (see [`Detector::guide`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuideWindow {
    /// ENU (m).
    pub centre: [f64; 2],
    pub radius: f64,
    /// Whether cells observed in this very map standing high join here at any hazard
    /// ([`GuideThresholds::fresh_min_points`]): for a track detected like a real object, not for
    /// wave glint, whose window would find such cells somewhere on the waves and let it walk on.
    pub fresh: bool,
    /// A component reaching into this window is never split (see [`DetectParams::split_min_cells`]):
    /// the window's track is a boat's, and what the window gathers around it is the boat and its
    /// smear (cut into bow and smear, a boat met head-on lost its track on cluttered_river, seed 58).
    pub keep_whole: bool,
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
    /// A component larger than this (cells, either axis) is split where it is dense (see
    /// [`Detector::detect`]); `u32::MAX` never splits.
    pub split_min_cells: u32,
    /// Along the line of sight from the vessel, cells also link across a gap that grows with
    /// the stereo range error (see [`LosLink`]); `None` links `link_cells` every way.
    pub los_link: Option<LosLink>,
}

/// A far object maps as fragments strung along the line of sight: stereo range error grows
/// with the square of range, and a boat met head-on 60-80 m out, read 2-3 m either side of its
/// hull, gave pieces of 1-8 cells, each a tentative track of its own, none confirmed until it was
/// about 58 m out (cluttered_river, seed 53). Two cells link when
/// their offset lies within `link_cells` across the line of sight and within
/// `max(link_cells, sigmas * sigma(range))` along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LosLink {
    /// The vessel, in cells (fractional column and row of the grid).
    pub origin: [f64; 2],
    /// Range sigma = `sigma_cells[0] + sigma_cells[1] * range`, range and sigma in cells.
    pub sigma_cells: [f64; 2],
    pub sigmas: f64,
    /// Cap on the along-line link (cells).
    pub max_cells: u32,
}

impl LosLink {
    /// The largest link of a cell at (`x`, `y`) and the unit line of sight there.
    fn at(&self, x: f64, y: f64, link: i64) -> (i64, [f64; 2]) {
        let (dx, dy) = (x - self.origin[0], y - self.origin[1]);
        let r = dx.hypot(dy);
        let along = (self.sigmas * (self.sigma_cells[0] + self.sigma_cells[1] * r))
            .min(self.max_cells as f64)
            .floor() as i64;
        let u = if r > 0.0 {
            [dx / r, dy / r]
        } else {
            [1.0, 0.0]
        };
        (along.max(link), u)
    }
}

#[derive(Default)]
pub struct Detector {
    label: Vec<u32>,
    stack: Vec<u32>,
    /// The cells of the component being described, and of its dense parts when split.
    members: Vec<u32>,
    part: Vec<u32>,
    /// `pass` marks: in the component being split (`member_mark`), taken by a part of it
    /// (`part_mark`).
    member_mark: Vec<u32>,
    part_mark: Vec<u32>,
    pass: u32,
    /// Cells marked with `guide_pass` lie in a guide window of the next `detect` ...
    guide_mark: Vec<u32>,
    /// ... and in one whose fresh cells join ([`GuideWindow::fresh`]) ...
    fresh_mark: Vec<u32>,
    /// ... and in one whose components stay whole ([`GuideWindow::keep_whole`]).
    whole_mark: Vec<u32>,
    guide_pass: u32,
    /// Thresholds inside the guide windows; `None` once the windows have been used.
    guided: Option<GuideThresholds>,
}

impl Detector {
    pub fn new() -> Self {
        Self::default()
    }

    /// Lowers the threshold of the next [`Detector::detect`] to `thresholds` inside the
    /// `windows` of `grid`. Applies to that one call only.
    pub fn guide(
        &mut self,
        grid: &GridGeometry,
        thresholds: GuideThresholds,
        windows: impl IntoIterator<Item = GuideWindow>,
    ) {
        let (w, h) = (grid.width as usize, grid.height as usize);
        if self.guide_mark.len() != w * h {
            self.guide_mark.clear();
            self.guide_mark.resize(w * h, 0);
            self.fresh_mark.clear();
            self.fresh_mark.resize(w * h, 0);
            self.whole_mark.clear();
            self.whole_mark.resize(w * h, 0);
            self.guide_pass = 0;
        }
        self.guide_pass = self.guide_pass.wrapping_add(1).max(1);
        self.guided = Some(thresholds);
        let r = grid.resolution_m;
        let west = grid.center[0] - w as f64 / 2.0 * r;
        let south = grid.center[1] - h as f64 / 2.0 * r;
        for GuideWindow {
            centre: [x, y],
            radius,
            fresh,
            keep_whole,
        } in windows
        {
            if !(x.is_finite() && y.is_finite() && radius.is_finite() && radius >= 0.0) {
                continue;
            }
            // Cell index range of the disc's bounding box, clamped to the grid.
            let span = |lo: f64, hi: f64, n: usize| {
                let a = (lo / r).floor().max(0.0);
                let b = ((hi / r).floor() + 1.0).min(n as f64);
                (a as usize, b.max(a) as usize)
            };
            let (c0, c1) = span(x - radius - west, x + radius - west, w);
            let (r0, r1) = span(y - radius - south, y + radius - south, h);
            for row in r0..r1 {
                let cy = south + (row as f64 + 0.5) * r;
                for col in c0..c1 {
                    let cx = west + (col as f64 + 0.5) * r;
                    if (cx - x).hypot(cy - y) <= radius {
                        self.guide_mark[row * w + col] = self.guide_pass;
                        if fresh {
                            self.fresh_mark[row * w + col] = self.guide_pass;
                        }
                        if keep_whole {
                            self.whole_mark[row * w + col] = self.guide_pass;
                        }
                    }
                }
            }
        }
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
            split_min_cells,
            los_link,
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
        // Guide windows (one-shot): cells marked for this call join from the lower thresholds.
        let guided = self
            .guided
            .take()
            .filter(|_| self.guide_mark.len() == w * h);
        let (marks, fresh_marks, mark) = (&self.guide_mark, &self.fresh_mark, self.guide_pass);
        let whole_marks = &self.whole_mark;
        let keep_whole = |i: usize| guided.is_some() && whole_marks[i] == mark;
        // Observed in this map, standing high, inside a window that takes such cells.
        let fresh = |i: usize| {
            guided.is_some_and(|g| {
                fresh_marks[i] == mark
                    && g.fresh_min_points > 0
                    && cells[i].observed >= g.fresh_min_points
                    && cells[i].max_height_cm >= g.lifted_height_cm
            })
        };
        let on = |i: usize| {
            let MapCell {
                hazard: hz,
                max_height_cm,
                ..
            } = cells[i];
            hz >= thr
                || guided.is_some_and(|g| {
                    marks[i] == mark
                        && hz >= 1
                        && (hz >= g.hazard
                            || (hz >= g.lifted_hazard && max_height_cm >= g.lifted_height_cm)
                            || fresh(i))
                })
        };
        if self.member_mark.len() != w * h {
            self.member_mark.clear();
            self.member_mark.resize(w * h, 0);
            self.part_mark.clear();
            self.part_mark.resize(w * h, 0);
        }
        let detection = |members: &[u32]| describe(grid, cells, members, thr, &fresh);
        for start in 0..w * h {
            if !on(start) || self.label[start] == pass {
                continue;
            }
            self.stack.clear();
            self.stack.push(start as u32);
            self.label[start] = pass;
            self.members.clear();
            let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
            let mut whole = false;
            while let Some(i) = self.stack.pop() {
                self.members.push(i);
                let i = i as usize;
                whole |= keep_whole(i);
                let (x, y) = (i % w, i / w);
                c0 = c0.min(x);
                c1 = c1.max(x);
                r0 = r0.min(y);
                r1 = r1.max(y);
                let (reach, los) = los_link.map_or((link, [1.0, 0.0]), |l| {
                    l.at(x as f64 + 0.5, y as f64 + 0.5, link)
                });
                for dy in -reach..=reach {
                    for dx in -reach..=reach {
                        // Beyond the square of `link`: only offsets near the line of sight, and
                        // no farther along it than `reach` (the square's corners lie farther).
                        if reach > link
                            && (dx.abs() > link || dy.abs() > link)
                            && ((dx as f64 * los[1] - dy as f64 * los[0]).abs() > link as f64
                                || (dx as f64 * los[0] + dy as f64 * los[1]).abs() > reach as f64)
                        {
                            continue;
                        }
                        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                        if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                            continue;
                        }
                        let j = ny as usize * w + nx as usize;
                        if on(j) && self.label[j] != pass {
                            self.label[j] = pass;
                            self.stack.push(j as u32);
                        }
                    }
                }
            }
            if (self.members.len() as u32) < min_cells {
                continue;
            }
            let large = (c1 - c0 + 1).max(r1 - r0 + 1) as u32 > split_min_cells && !whole;
            if !large {
                if out.len() < max {
                    out.push(detection(&self.members));
                }
                continue;
            }
            // A component larger than any boat: a bank, or a bank with the boats moored along it,
            // which the stereo smear of tens of metres of range joins to it. Its dense parts (cells
            // with `SPLIT_CORE_NEIGHBOURS` of their 8 neighbours in the component) fall apart where
            // the join is sparse; each compact one, with the component's cells touching it, is a
            // detection of its own, and the rest stays one.
            for &i in &self.members {
                self.member_mark[i as usize] = pass;
            }
            let member = |marks: &[u32], x: i64, y: i64| {
                x >= 0
                    && y >= 0
                    && x < w as i64
                    && y < h as i64
                    && marks[y as usize * w + x as usize] == pass
            };
            let dense = |marks: &[u32], i: usize| {
                let (x, y) = ((i % w) as i64, (i / w) as i64);
                NEIGHBOURS
                    .iter()
                    .filter(|(dx, dy)| member(marks, x + dx, y + dy))
                    .count()
                    >= SPLIT_CORE_NEIGHBOURS
            };
            for k in 0..self.members.len() {
                let seed = self.members[k] as usize;
                if self.part_mark[seed] == pass || !dense(&self.member_mark, seed) {
                    continue;
                }
                // One dense part, 8-connected, then the component's cells touching it.
                self.part.clear();
                self.part.push(seed as u32);
                self.part_mark[seed] = pass;
                let mut next = 0;
                let (mut p0, mut p1, mut q0, mut q1) = (usize::MAX, 0, usize::MAX, 0);
                while next < self.part.len() {
                    let i = self.part[next] as usize;
                    next += 1;
                    let (x, y) = (i % w, i / w);
                    (p0, p1, q0, q1) = (p0.min(x), p1.max(x), q0.min(y), q1.max(y));
                    for (dx, dy) in NEIGHBOURS {
                        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                        if !member(&self.member_mark, nx, ny) {
                            continue;
                        }
                        let j = ny as usize * w + nx as usize;
                        if self.part_mark[j] != pass && dense(&self.member_mark, j) {
                            self.part_mark[j] = pass;
                            self.part.push(j as u32);
                        }
                    }
                }
                let core = self.part.len();
                let compact = (p1 - p0 + 1).max(q1 - q0 + 1) as u32 <= split_min_cells / 2;
                if !compact || (core as u32) < SPLIT_MIN_PART_CELLS {
                    // Left to the rest; its cells stay marked, so it is not walked again.
                    continue;
                }
                for n in 0..core {
                    let i = self.part[n] as usize;
                    let (x, y) = ((i % w) as i64, (i / w) as i64);
                    for (dx, dy) in NEIGHBOURS {
                        if !member(&self.member_mark, x + dx, y + dy) {
                            continue;
                        }
                        let j = (y + dy) as usize * w + (x + dx) as usize;
                        if self.part_mark[j] != pass {
                            self.part_mark[j] = pass;
                            self.part.push(j as u32);
                        }
                    }
                }
                if out.len() < max {
                    out.push(Detection {
                        in_large_component: true,
                        ..detection(&self.part)
                    });
                }
                // Marked as taken by a compact part: excluded from the rest below.
                for &i in &self.part {
                    self.member_mark[i as usize] = pass.wrapping_sub(1);
                }
            }
            let member_mark = &self.member_mark;
            self.members.retain(|&i| member_mark[i as usize] == pass);
            if self.members.len() as u32 >= min_cells && out.len() < max {
                out.push(Detection {
                    in_large_component: true,
                    ..detection(&self.members)
                });
            }
        }
    }
}

/// The 8 neighbours of a cell.
const NEIGHBOURS: [(i64, i64); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// A cell of a large component with this many of its 8 neighbours in the component lies in a
/// dense part of it (see [`Detector::detect`]). 5: on cluttered_river's recorded maps it cut the
/// two moored boats 9 m off the east bank (80 and 111 cells) from the bank (735), which 4 also
/// did with each part a cell wider.
const SPLIT_CORE_NEIGHBOURS: usize = 5;

/// A dense part smaller than this (cells) is left to the rest of its component: a speck of the
/// bank's edge is no object.
const SPLIT_MIN_PART_CELLS: u32 = 12;

/// The detection of component `members` of `cells` over `grid`: hazard-weighted moments, extent,
/// height, peak, and the cells observed in this map or standing high inside a fresh window.
fn describe(
    grid: &GridGeometry,
    cells: &[MapCell],
    members: &[u32],
    thr: u8,
    fresh: &impl Fn(usize) -> bool,
) -> Detection {
    let w = grid.width as usize;
    let r = grid.resolution_m;
    // Hazard-weighted moments in cell units.
    let (mut sw, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0f64, 0f64, 0f64, 0f64, 0f64, 0f64);
    let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
    let (mut hmax, mut peak) = (i16::MIN, 0u8);
    let (mut fresh_n, mut fresh_x, mut fresh_y) = (0u32, 0f64, 0f64);
    let mut observed_n = 0u32;
    for &i in members {
        let i = i as usize;
        let (x, y) = (i % w, i / w);
        let c = cells[i];
        let wgt = c.hazard as f64 / 255.0;
        sw += wgt;
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
        peak = peak.max(c.hazard);
        observed_n += u32::from(c.observed > 0 && c.hazard >= thr);
        if fresh(i) {
            fresh_n += 1;
            fresh_x += fx;
            fresh_y += fy;
        }
    }
    let n = members.len() as u32;
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
    let at = |cx: f64, cy: f64| [west + (cx + 0.5) * r, south + (cy + 0.5) * r];
    let position = at(mx, my);
    let (sight, _) =
        line_of_sight::direction([position[0] - grid.center[0], position[1] - grid.center[1]]);
    let (along_var, across_var) = line_of_sight::along_across_variances(sight, [vxx, vxy, vyy]);
    Detection {
        position,
        extent: [(c1 - c0 + 1) as f64 * r, (r1 - r0 + 1) as f64 * r],
        area: n as f64 * r * r,
        height: hmax.max(0) as f64 / 100.0,
        elongation: (l1 / l2).sqrt(),
        mean_hazard: sw / n as f64,
        along_sd_m: along_var.max(0.0).sqrt() * r,
        across_sd_m: across_var.max(0.0).sqrt() * r,
        peak_hazard: peak,
        cells: n,
        fresh_cells: fresh_n,
        fresh_position: if fresh_n > 0 {
            at(fresh_x / fresh_n as f64, fresh_y / fresh_n as f64)
        } else {
            at(mx, my)
        },
        observed_cells: observed_n,
        in_large_component: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_is_measured_along_and_across_the_line_of_sight() {
        // The vessel at the map's centre (0, 0); 0.5 m cells, the grid 40 m wide.
        let grid = GridGeometry {
            width: 80,
            height: 80,
            resolution_m: 0.5,
            center: [0.0, 0.0],
        };
        let mut cells = vec![MapCell::default(); 80 * 80];
        // Due east of the vessel: a bar 10 cells long east-west (along the line of sight) and,
        // due north, one 10 cells long east-west (across it).
        for k in 0..10 {
            cells[40 * 80 + 65 + k].hazard = 255;
            cells[70 * 80 + 35 + k].hazard = 255;
        }
        let mut out = Vec::new();
        let params = DetectParams {
            threshold: 128,
            min_cells: 1,
            max: 4,
            link_cells: 1,
            split_min_cells: u32::MAX,
            los_link: None,
        };
        Detector::new().detect(&grid, &cells, &params, &mut out);
        let east = out.iter().find(|d| d.position[0] > 10.0).unwrap();
        let north = out.iter().find(|d| d.position[1] > 10.0).unwrap();
        // Ten cells in a row: sd sqrt((10^2 - 1) / 12 + 1 / 12) cells = 1.44 m; one cell across:
        // sqrt(1 / 12) cells = 0.14 m.
        let (long, thin) = ((100.0f64 / 12.0).sqrt() * 0.5, (1.0f64 / 12.0).sqrt() * 0.5);
        assert!((east.along_sd_m - long).abs() < 0.02, "{}", east.along_sd_m);
        assert!(
            (east.across_sd_m - thin).abs() < 0.02,
            "{}",
            east.across_sd_m
        );
        assert!(
            (north.along_sd_m - thin).abs() < 0.02,
            "{}",
            north.along_sd_m
        );
        assert!(
            (north.across_sd_m - long).abs() < 0.02,
            "{}",
            north.across_sd_m
        );
    }

    #[test]
    fn a_boat_moored_by_a_bank_is_split_from_it_where_the_join_is_sparse() {
        // 0.5 m cells, the map's centre at the origin (grid 100x100, south-west corner -25, -25).
        let grid = GridGeometry {
            width: 100,
            height: 100,
            resolution_m: 0.5,
            center: [0.0, 0.0],
        };
        let mut cells = vec![MapCell::default(); 100 * 100];
        let mut set = |x: usize, y: usize| {
            cells[y * 100 + x] = MapCell {
                hazard: 255,
                max_height_cm: 200,
                ..Default::default()
            };
        };
        // A bank 40 m long and 5 m deep along the east edge ...
        for y in 10..90 {
            for x in 80..90 {
                set(x, y);
            }
        }
        // ... a boat 3 x 6 m, 4 m off it ...
        for y in 44..56 {
            for x in 66..72 {
                set(x, y);
            }
        }
        // ... and a sparse line of cells (the stereo smear) joining them, every other cell.
        for x in (73..80).step_by(2) {
            set(x, 50);
        }
        let mut d = Detector::new();
        let mut out = Vec::new();
        let params = |split_min_cells| DetectParams {
            threshold: 128,
            min_cells: 1,
            max: 16,
            link_cells: 3,
            split_min_cells,
            los_link: None,
        };
        d.detect(&grid, &cells, &params(u32::MAX), &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        // Split above 30 m: the boat's cells and the ones touching it, and the rest.
        d.detect(&grid, &cells, &params(60), &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        let boat = out
            .iter()
            .find(|d| d.extent[0].max(d.extent[1]) < 15.0)
            .unwrap();
        // Cell centres x 66..72 -> 8.25..10.75 m east, y 44..56 -> -2.75..2.75 m north.
        assert!((boat.position[0] - 9.5).abs() < 0.3, "{boat:?}");
        assert!(boat.position[1].abs() < 0.3, "{boat:?}");
        assert!(boat.cells >= 72 && boat.cells <= 80, "{boat:?}");
        let bank = out.iter().find(|d| d.extent[1] >= 39.0).unwrap();
        assert_eq!(bank.cells + boat.cells, 800 + 72 + 4);
        // Nor one reaching into the guide window of a boat-sized track: a moving boat and the
        // smear its window gathered.
        d.guide(&grid, guided(128), [window([9.5, 0.0], 2.0, false)]);
        d.detect(&grid, &cells, &params(60), &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        // A component of the boat's own size is never split.
        let mut small = vec![MapCell::default(); 100 * 100];
        for i in (0..100 * 100).filter(|&i| cells[i].hazard > 0 && i % 100 < 73) {
            small[i] = cells[i];
        }
        d.detect(&grid, &small, &params(60), &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
    }

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
            split_min_cells: u32::MAX,
            los_link: None,
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

    /// Two fragments of a boat 70 m out, 2 m apart: along the line of sight (the stereo range
    /// smear) they are one detection, across it two, and without the line-of-sight link two.
    #[test]
    fn fragments_far_out_link_along_the_line_of_sight_not_across_it() {
        // 20 m square centred 70 m east of the vessel at the origin, 0.5 m cells.
        let grid = GridGeometry {
            width: 40,
            height: 40,
            resolution_m: 0.5,
            center: [70.0, 0.0],
        };
        let vessel = [0.0, 0.0];
        let los = LosLink {
            origin: [
                (vessel[0] - grid.center[0]) / 0.5 + 20.0,
                (vessel[1] - grid.center[1]) / 0.5 + 20.0,
            ],
            // 0.3 m + 0.03 per metre (2.4 m at 70 m), 1.5 sigmas, capped at 3 m.
            sigma_cells: [0.6, 0.03],
            sigmas: 1.5,
            max_cells: 6,
        };
        let params = |los_link| DetectParams {
            threshold: 128,
            min_cells: 1,
            max: 16,
            link_cells: 3,
            split_min_cells: u32::MAX,
            los_link,
        };
        let pair = |gap: (usize, usize)| {
            let mut cells = vec![MapCell::default(); 1600];
            for (x, y) in [
                (10, 20),
                (11, 20),
                (10 + gap.0, 20 + gap.1),
                (11 + gap.0, 20 + gap.1),
            ] {
                cells[y * 40 + x].hazard = 200;
            }
            cells
        };
        let mut d = Detector::new();
        let mut out = Vec::new();
        // 4 cells (2 m) apart in x, the line of sight (east); then in y, across it.
        d.detect(&grid, &pair((5, 0)), &params(Some(los)), &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!(out[0].cells, 4);
        d.detect(&grid, &pair((0, 5)), &params(Some(los)), &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        d.detect(&grid, &pair((5, 0)), &params(None), &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        // 4 m apart along the line of sight: beyond the 3 m cap.
        d.detect(&grid, &pair((9, 0)), &params(Some(los)), &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        // The same 70 m out to the north-east: 2.8 m apart along the diagonal line of sight link,
        // 4.2 m (within the square of the 3 m cap, beyond the cap along the line) do not.
        let diagonal = GridGeometry {
            center: [49.5, 49.5],
            ..grid
        };
        let los = LosLink {
            origin: [-99.0 + 20.0, -99.0 + 20.0],
            ..los
        };
        let pair = |gap: usize| {
            let mut cells = vec![MapCell::default(); 1600];
            for (x, y) in [(10, 10), (11, 11), (11 + gap, 11 + gap)] {
                cells[y * 40 + x].hazard = 200;
            }
            cells
        };
        d.detect(&diagonal, &pair(4), &params(Some(los)), &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        d.detect(&diagonal, &pair(6), &params(Some(los)), &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
    }

    /// 20 m x 10 m around the origin, 0.5 m cells (row 10 is y = 0.25).
    fn guide_test_grid() -> GridGeometry {
        GridGeometry {
            width: 40,
            height: 20,
            resolution_m: 0.5,
            center: [0.0, 0.0],
        }
    }

    /// The tracker's full threshold, 8-connected.
    const GUIDE_TEST_PARAMS: DetectParams = DetectParams {
        threshold: 128,
        min_cells: 1,
        max: 16,
        link_cells: 1,
        split_min_cells: u32::MAX,
        los_link: None,
    };

    #[test]
    fn guide_windows_lower_the_threshold_once_and_only_inside() {
        let grid = guide_test_grid();
        // Two equal strips of weak evidence (hazard 85 of 255, below the 128 threshold):
        // a boat's path near (-5, 0) and wave glint near (5, 0).
        let mut cells = vec![MapCell::default(); 800];
        for x in [8usize, 9, 10, 11, 12, 28, 29, 30, 31, 32] {
            cells[10 * 40 + x].hazard = 85;
        }
        let params = GUIDE_TEST_PARAMS;
        let mut d = Detector::new();
        let mut out = Vec::new();
        d.detect(&grid, &cells, &params, &mut out);
        assert!(out.is_empty());
        // A track is expected at the west strip: it is detected whole, the east one is not.
        d.guide(&grid, guided(64), [window([-5.0, 0.0], 3.0, false)]);
        d.detect(&grid, &cells, &params, &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].cells, 5);
        assert_eq!(out[0].peak_hazard, 85);
        assert!((out[0].position[0] + 4.75).abs() < 1e-9, "{:?}", out[0]);
        // The guide applied to that one call.
        d.detect(&grid, &cells, &params, &mut out);
        assert!(out.is_empty());
        // A guided threshold above the strip's evidence finds nothing either.
        d.guide(&grid, guided(100), [window([-5.0, 0.0], 3.0, false)]);
        d.detect(&grid, &cells, &params, &mut out);
        assert!(out.is_empty());
    }

    fn window(centre: [f64; 2], radius: f64, fresh: bool) -> GuideWindow {
        GuideWindow {
            centre,
            radius,
            fresh,
            keep_whole: true,
        }
    }

    /// Guide thresholds without the lifted rule.
    fn guided(hazard: u8) -> GuideThresholds {
        GuideThresholds {
            hazard,
            lifted_hazard: hazard,
            lifted_height_cm: 0,
            fresh_min_points: 0,
        }
    }

    #[test]
    fn inside_a_guide_window_a_lifted_cell_joins_from_a_lower_hazard_and_a_flat_one_does_not() {
        let grid = guide_test_grid();
        // A stern seen once in the average (hazard 70, 1.6 m above the water) beside glint of the
        // same hazard lying on the water, both in one window.
        let mut cells = vec![MapCell::default(); 800];
        for (xs, max_height_cm) in [(8..12, 160), (20..24, 10)] {
            for x in xs {
                cells[10 * 40 + x] = MapCell {
                    hazard: 70,
                    max_height_cm,
                    ..MapCell::default()
                };
            }
        }
        let params = GUIDE_TEST_PARAMS;
        let thresholds = GuideThresholds {
            hazard: 96,
            lifted_hazard: 64,
            lifted_height_cm: 100,
            fresh_min_points: 0,
        };
        let mut d = Detector::new();
        let mut out = Vec::new();
        d.guide(&grid, thresholds, [window([-2.0, 0.0], 8.0, false)]);
        d.detect(&grid, &cells, &params, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!(out[0].cells, 4);
        assert!((out[0].position[0] + 5.0).abs() < 1e-9, "{:?}", out[0]);
        assert!((out[0].height - 1.6).abs() < 1e-9);
        // Outside a window the lifted cells are below the threshold like any other.
        d.detect(&grid, &cells, &params, &mut out);
        assert!(out.is_empty());
        // Below the lifted threshold they do not join either.
        d.guide(
            &grid,
            GuideThresholds {
                lifted_hazard: 71,
                ..thresholds
            },
            [window([-2.0, 0.0], 8.0, false)],
        );
        d.detect(&grid, &cells, &params, &mut out);
        assert!(out.is_empty());
    }
    #[test]
    fn inside_a_guide_window_cells_seen_standing_high_in_this_map_join_and_place_the_hull() {
        let grid = guide_test_grid();
        // A boat heading east seen from astern: its transom (x = -3 .. -2 m) observed in this map
        // by 60 points 2 m high but at little hazard (a first sighting), the smear of the frames
        // before astern of it (x = -6 .. -3 m) at 110, not observed this map.
        let mut cells = vec![MapCell::default(); 800];
        for y in 9..12 {
            for x in 14..16 {
                cells[y * 40 + x] = MapCell {
                    hazard: 30,
                    observed: 60,
                    max_height_cm: 200,
                    ..MapCell::default()
                };
            }
            for x in 8..14 {
                cells[y * 40 + x] = MapCell {
                    hazard: 110,
                    observed: 0,
                    max_height_cm: 200,
                    ..MapCell::default()
                };
            }
        }
        // One stray point standing high in the same window, alone in its cell.
        cells[15 * 40 + 14] = MapCell {
            hazard: 20,
            observed: 1,
            max_height_cm: 300,
            ..MapCell::default()
        };
        let thresholds = GuideThresholds {
            hazard: 96,
            lifted_hazard: 64,
            lifted_height_cm: 100,
            fresh_min_points: 4,
        };
        let mut d = Detector::new();
        let mut out = Vec::new();
        d.guide(&grid, thresholds, [window([-4.0, 0.0], 6.0, true)]);
        d.detect(&grid, &cells, &GUIDE_TEST_PARAMS, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        let boat = out[0];
        assert_eq!((boat.cells, boat.fresh_cells), (24, 6));
        // The hazard-weighted centroid lies in the smear (-4.3 m); the fresh one on the transom.
        assert!(boat.position[0] < -4.0, "{boat:?}");
        assert!((boat.fresh_position[0] + 2.5).abs() < 1e-9, "{boat:?}");
        assert!((boat.fresh_position[1] - 0.25).abs() < 1e-9, "{boat:?}");
        // Off, the transom is below every threshold: the smear alone, with no fresh cells.
        d.guide(
            &grid,
            GuideThresholds {
                fresh_min_points: 0,
                ..thresholds
            },
            [window([-4.0, 0.0], 6.0, true)],
        );
        d.detect(&grid, &cells, &GUIDE_TEST_PARAMS, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!((out[0].cells, out[0].fresh_cells), (18, 0));
        assert_eq!(out[0].fresh_position, out[0].position);
        // So in a window that does not take fresh cells (a glint track's).
        d.guide(&grid, thresholds, [window([-4.0, 0.0], 6.0, false)]);
        d.detect(&grid, &cells, &GUIDE_TEST_PARAMS, &mut out);
        assert_eq!((out.len(), out[0].fresh_cells), (1, 0), "{out:?}");
        // Outside a window nothing joins.
        d.detect(&grid, &cells, &GUIDE_TEST_PARAMS, &mut out);
        assert!(out.is_empty(), "{out:?}");
    }
}
