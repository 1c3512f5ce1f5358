//! Perception figures of `usv eval`: water detection and the hazard map, scored against the
//! simulator's ground truth while the run goes on.
//!
//! - **Water** (the perception service's `WaterMask` of the truth head): per frame, each true water
//!   body in view (at least `min_truth_pixels` of its pixels, found by back-projecting the per-pixel
//!   truth) is detected when fused water covers a share of its pixels; detection is counted per
//!   range bin. An accepted region (a connected component of fused water) is false when little of it
//!   lies on true water; the report gives the share of frames with at least one. The scoring itself
//!   is the `water` library's (`water::eval`). Water cells of the local maps are checked against the
//!   true bodies' outlines and elevations.
//! - **Hazard map** (every `LocalMap`): per buoy, marker, pylon and boat in range, the share of
//!   frames in which it was observed and detected; cell-level precision and recall summed over the
//!   frames, by `perception::eval`.
//!
//! Only reads topics; each message is matched with the ground truth of its stamp.

use messages::{
    topics, water_cue, CameraModel, GroundTruth, LocalMapHeader, MapCell, TruthImageHeader,
    WaterMaskHeader,
};
use perception::eval::{score_hazard_map, HazardScore, MapPlacement, ScoreParams};
use runtime::Ports;
use serde_json::json;
use std::collections::BTreeMap;
use water::eval::{assign_bodies, score_frame, EvalParams, RangeTable, TruthBody};

/// Upper edges of the water range bins (m); the last bin is open.
const WATER_EDGES: [f64; 6] = [5.0, 7.0, 10.0, 15.0, 20.0, 30.0];
/// A local-map water cell is on a body when its centre is within this of the outline (m).
const CELL_SLACK_M: f64 = 0.5;
/// Messages kept per stamp while their partners are missing.
const PENDING: usize = 16;

/// The tracker's detection threshold in the simulated sets (`launch/sets/tracker.toml`): the world
/// map's hazard cells are scored at the value that makes contacts of them.
const WORLD_HAZARD_THRESHOLD: u8 = 128;

/// Cell precision and recall summed over maps.
#[derive(Default)]
struct CellTally {
    maps: u64,
    hazard: usize,
    true_hazard: usize,
    footprint: usize,
    found: usize,
}

impl CellTally {
    fn add(&mut self, s: &HazardScore) {
        self.maps += 1;
        self.hazard += s.hazard_cells;
        self.true_hazard += s.true_hazard_cells;
        self.footprint += s.footprint_cells;
        self.found += s.footprint_cells_found;
    }

    fn precision(&self) -> Option<f64> {
        (self.hazard > 0).then(|| round4(self.true_hazard as f64 / self.hazard as f64))
    }

    fn recall(&self) -> Option<f64> {
        (self.footprint > 0).then(|| round4(self.found as f64 / self.footprint as f64))
    }
}

/// Where a map of the vessel at `ins` (its INS position) lies, with the INS error against truth.
fn placement(
    grid: &messages::GridGeometry,
    ins: &messages::Pose,
    truth: &GroundTruth,
) -> MapPlacement {
    let own = truth.own.pose.position;
    MapPlacement {
        grid: *grid,
        vessel: [ins.position[0], ins.position[1]],
        placement_error: [ins.position[0] - own[0], ins.position[1] - own[1]],
    }
}

/// Per-object hazard-map figures.
#[derive(Default, Clone, Copy)]
struct ObjectTally {
    class: u8,
    observed: u32,
    detected: u32,
    nearest_m: f64,
}

/// A false water region: time since the first mask, size, share on true water, pixels carrying
/// each cue (colour, texture, reflection, zero disparity), mean image row.
struct FalseRegion {
    time_ns: u64,
    pixels: u32,
    share_on_water: f32,
    cues: [u32; 4],
    mean_row: u32,
}

/// Per-body water figures.
#[derive(Default, Clone)]
struct BodyTally {
    seen: Vec<u32>,
    detected: Vec<u32>,
}

pub struct PerceptionEval {
    head: String,
    masks: runtime::Subscriber<[u8], WaterMaskHeader>,
    truth_images: runtime::Subscriber<[f32], TruthImageHeader>,
    truth: runtime::Subscriber<GroundTruth, ()>,
    disparity: runtime::Subscriber<[f32], messages::DisparityHeader>,
    local_maps: runtime::Subscriber<[MapCell], LocalMapHeader>,
    world_maps: runtime::Subscriber<[MapCell], messages::WorldMapHeader>,
    pending_masks: BTreeMap<u64, (WaterMaskHeader, Vec<u8>)>,
    pending_images: BTreeMap<u64, (TruthImageHeader, Vec<f32>)>,
    pending_truth: BTreeMap<u64, Box<GroundTruth>>,
    pending_maps: BTreeMap<u64, (LocalMapHeader, Vec<MapCell>)>,
    pending_world: BTreeMap<u64, (messages::WorldMapHeader, Vec<MapCell>)>,
    cameras: BTreeMap<u64, CameraModel>,
    // Water.
    water_frames: u64,
    unscored_masks: u64,
    false_frames: u64,
    water_pixels: u64,
    water_pixels_on_truth: u64,
    truth_pixels: u64,
    truth_pixels_found: u64,
    ranges: RangeTable,
    bodies: BTreeMap<u32, BodyTally>,
    /// The first false regions, for looking at them.
    false_regions: Vec<FalseRegion>,
    first_stamp: Option<u64>,
    map_water_cells: u64,
    map_water_cells_on_body: u64,
    map_water_cells_on_body_registered: u64,
    elevation_errors_m: Vec<f64>,
    // Hazard map.
    objects: BTreeMap<u32, ObjectTally>,
    local_cells: CellTally,
    world_cells: CellTally,
    // Scratch.
    labels: Vec<u8>,
    body_of: Vec<u16>,
    body_ranges: Vec<f64>,
    regions: Vec<u32>,
    binary: Vec<u8>,
    parent: Vec<u32>,
}

impl PerceptionEval {
    /// Watches the water masks and truth images of `head` and every local map.
    pub fn new(
        node: &iceoryx2::node::Node<iceoryx2::prelude::ipc::Service>,
        head: &str,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            head: head.to_string(),
            masks: topics::WATER_MASK.subscriber(node)?,
            truth_images: topics::TRUTH_IMAGE.subscriber(node)?,
            truth: topics::GROUND_TRUTH.subscriber(node)?,
            disparity: topics::DISPARITY.subscriber(node)?,
            local_maps: topics::LOCAL_MAP.subscriber(node)?,
            world_maps: topics::WORLD_MAP.subscriber(node)?,
            pending_masks: BTreeMap::new(),
            pending_images: BTreeMap::new(),
            pending_truth: BTreeMap::new(),
            pending_maps: BTreeMap::new(),
            pending_world: BTreeMap::new(),
            cameras: BTreeMap::new(),
            water_frames: 0,
            unscored_masks: 0,
            false_frames: 0,
            water_pixels: 0,
            water_pixels_on_truth: 0,
            truth_pixels: 0,
            truth_pixels_found: 0,
            ranges: RangeTable::new(&WATER_EDGES),
            bodies: BTreeMap::new(),
            false_regions: Vec::new(),
            first_stamp: None,
            map_water_cells: 0,
            map_water_cells_on_body: 0,
            map_water_cells_on_body_registered: 0,
            elevation_errors_m: Vec::new(),
            objects: BTreeMap::new(),
            local_cells: CellTally::default(),
            world_cells: CellTally::default(),
            labels: Vec::new(),
            body_of: Vec::new(),
            body_ranges: Vec::new(),
            regions: Vec::new(),
            binary: Vec::new(),
            parent: Vec::new(),
        })
    }

    /// Takes in what arrived and scores every frame whose parts are all in.
    pub fn poll(&mut self) -> anyhow::Result<()> {
        while let Some(s) = self.truth.receive()? {
            let t = Box::new(*s.payload());
            self.pending_truth.insert(t.hdr.stamp_ns, t);
        }
        while let Some(s) = self.disparity.receive()? {
            let h = s.user_header();
            if h.head.as_str() == self.head {
                self.cameras.insert(h.hdr.stamp_ns, h.camera);
            }
        }
        while let Some(s) = self.truth_images.receive()? {
            let h = *s.user_header();
            if h.head.as_str() == self.head {
                self.pending_images
                    .insert(h.hdr.stamp_ns, (h, s.payload().to_vec()));
            }
        }
        while let Some(s) = self.masks.receive()? {
            let h = *s.user_header();
            if h.head.as_str() == self.head {
                self.pending_masks
                    .insert(h.hdr.stamp_ns, (h, s.payload().to_vec()));
            }
        }
        while let Some(s) = self.local_maps.receive()? {
            let h = *s.user_header();
            self.pending_maps
                .insert(h.hdr.stamp_ns, (h, s.payload().to_vec()));
        }
        let ready: Vec<u64> = self
            .pending_masks
            .keys()
            .copied()
            .filter(|s| {
                self.pending_images.contains_key(s)
                    && self.pending_truth.contains_key(s)
                    && self.cameras.contains_key(s)
            })
            .collect();
        for stamp in ready {
            let (mh, mask) = self.pending_masks.remove(&stamp).unwrap();
            let (th, image) = self.pending_images.remove(&stamp).unwrap();
            let camera = self.cameras[&stamp];
            let truth = self.pending_truth[&stamp].clone();
            self.score_water(&mh, &mask, &th, &image, &camera, &truth);
        }
        while let Some(s) = self.world_maps.receive()? {
            let h = *s.user_header();
            self.pending_world
                .insert(h.hdr.stamp_ns, (h, s.payload().to_vec()));
        }
        for (stamp, (h, cells)) in take_ready(&mut self.pending_maps, &self.pending_truth) {
            let truth = self.pending_truth[&stamp].clone();
            self.score_map(&h, &cells, &truth)?;
        }
        for (stamp, (h, cells)) in take_ready(&mut self.pending_world, &self.pending_truth) {
            let truth = &self.pending_truth[&stamp];
            let params = ScoreParams {
                hazard_threshold: WORLD_HAZARD_THRESHOLD,
                ..ScoreParams::default()
            };
            let s = score_hazard_map(
                &placement(&h.grid, &h.vessel, truth),
                &cells,
                truth,
                &params,
            )?;
            self.world_cells.add(&s);
        }
        trim(&mut self.pending_masks);
        trim(&mut self.pending_images);
        trim(&mut self.pending_truth);
        trim(&mut self.pending_maps);
        trim(&mut self.pending_world);
        trim(&mut self.cameras);
        Ok(())
    }

    fn score_water(
        &mut self,
        mh: &WaterMaskHeader,
        mask: &[u8],
        th: &TruthImageHeader,
        image: &[f32],
        camera: &CameraModel,
        truth: &GroundTruth,
    ) {
        let n = mask.len();
        if (mh.width, mh.height) != (th.width, th.height) || image.len() != 2 * n {
            self.unscored_masks += 1;
            return;
        }
        let (truth_disparity, label_plane) = image.split_at(n);
        self.labels.clear();
        self.labels
            .extend(label_plane.iter().map(|&l| l.clamp(0.0, 255.0) as u8));
        let bodies: Vec<TruthBody> = truth
            .water()
            .iter()
            .map(|w| TruthBody {
                id: w.id,
                center: w.center,
                radii: w.radii,
                elevation_m: w.elevation_m,
            })
            .collect();
        let w = mh.width as usize;
        assign_bodies(
            w,
            &self.labels,
            truth_disparity,
            camera,
            &truth.own.pose,
            &bodies,
            &mut self.body_of,
            &mut self.body_ranges,
        );
        let accepted = label_components(
            mask,
            w,
            &mut self.regions,
            &mut self.binary,
            &mut self.parent,
        );
        let score = score_frame(
            &self.body_of,
            &self.body_ranges,
            &bodies,
            mask,
            &self.regions,
            &accepted,
            &EvalParams::default(),
        );
        self.water_frames += 1;
        self.false_frames += score.has_false_region() as u64;
        let first = *self.first_stamp.get_or_insert(mh.hdr.stamp_ns);
        for r in score.regions.iter().filter(|r| r.is_false) {
            if self.false_regions.len() < 20 {
                // Which cues made it, and where (mean row), to tell what fooled the rule base.
                let (mut cues, mut rows) = ([0u32; 4], 0u64);
                for (i, _) in self
                    .regions
                    .iter()
                    .enumerate()
                    .filter(|(_, &l)| l == r.label)
                {
                    for (k, bit) in [
                        water_cue::COLOR,
                        water_cue::TEXTURE,
                        water_cue::REFLECTION,
                        water_cue::ZERO_DISPARITY,
                    ]
                    .into_iter()
                    .enumerate()
                    {
                        cues[k] += (mask[i] & bit != 0) as u32;
                    }
                    rows += (i / w) as u64;
                }
                self.false_regions.push(FalseRegion {
                    time_ns: mh.hdr.stamp_ns.saturating_sub(first),
                    pixels: r.pixels,
                    share_on_water: r.truth_share,
                    cues,
                    mean_row: (rows / r.pixels.max(1) as u64) as u32,
                });
            }
        }
        for (i, &m) in mask.iter().enumerate() {
            let water = m & water_cue::WATER != 0;
            let on_truth = self.body_of[i] > 0;
            self.water_pixels += water as u64;
            self.water_pixels_on_truth += (water && on_truth) as u64;
            self.truth_pixels += on_truth as u64;
            self.truth_pixels_found += (water && on_truth) as u64;
        }
        let bins = WATER_EDGES.len() + 1;
        for b in &score.bodies {
            self.ranges.add(b);
            let k = self.ranges.bin(b.range_m);
            let t = self.bodies.entry(b.id).or_insert_with(|| BodyTally {
                seen: vec![0; bins],
                detected: vec![0; bins],
            });
            t.seen[k] += 1;
            t.detected[k] += b.detected as u32;
        }
    }

    fn score_map(
        &mut self,
        h: &LocalMapHeader,
        cells: &[MapCell],
        truth: &GroundTruth,
    ) -> anyhow::Result<()> {
        let g = &h.grid;
        if cells.len() != g.cell_count() {
            return Ok(());
        }
        // The map is placed with the INS (1 m position noise in the simulator): cells are compared
        // with the truth both as placed and moved by the INS error of the frame (what perception
        // itself got right), and elevations relative to the vehicle.
        let ins = h.vessel.position;
        let own = truth.own.pose.position;
        let inside = |e: f64, n: f64| {
            truth.water().iter().find(|b| {
                ((e - b.center[0]) / (b.radii[0] + CELL_SLACK_M)).powi(2)
                    + ((n - b.center[1]) / (b.radii[1] + CELL_SLACK_M)).powi(2)
                    <= 1.0
            })
        };
        for (i, c) in cells.iter().enumerate().filter(|(_, c)| c.water > 0) {
            self.map_water_cells += 1;
            let [e, n] = g.cell_center(i as u32 % g.width, i as u32 / g.width);
            self.map_water_cells_on_body += inside(e, n).is_some() as u64;
            let (e, n) = (e - ins[0] + own[0], n - ins[1] + own[1]);
            if let Some(b) = inside(e, n) {
                self.map_water_cells_on_body_registered += 1;
                self.elevation_errors_m
                    .push((c.elevation_cm as f64 / 100.0 - ins[2]) - (b.elevation_m - own[2]));
            }
        }
        let s = score_hazard_map(
            &placement(g, &h.vessel, truth),
            cells,
            truth,
            &ScoreParams::default(),
        )?;
        for o in &s.objects {
            let t = self.objects.entry(o.id).or_insert(ObjectTally {
                class: o.class,
                nearest_m: f64::INFINITY,
                ..Default::default()
            });
            t.observed += o.observed as u32;
            t.detected += (o.observed && o.detected) as u32;
            if o.observed {
                t.nearest_m = t.nearest_m.min(o.range_m);
            }
        }
        self.local_cells.add(&s);
        Ok(())
    }

    /// The figures as JSON (`water` is null when no water mask was scored).
    pub fn report(&self) -> serde_json::Value {
        let rate = |d: u64, s: u64| (s > 0).then(|| round4(d as f64 / s as f64));
        let bin_name = |k: usize| match k {
            0 => format!("<{}", WATER_EDGES[0]),
            k if k == WATER_EDGES.len() => format!(">={}", WATER_EDGES[k - 1]),
            k => format!("{}-{}", WATER_EDGES[k - 1], WATER_EDGES[k]),
        };
        let by_range: Vec<_> = (0..=WATER_EDGES.len())
            .map(|k| {
                json!({"range_m": bin_name(k), "seen": self.ranges.seen[k],
                       "detected": self.ranges.detected[k],
                       "rate": rate(self.ranges.detected[k] as u64, self.ranges.seen[k] as u64)})
            })
            .collect();
        let bodies: Vec<_> = self
            .bodies
            .iter()
            .map(|(id, t)| {
                let bins: Vec<_> = (0..t.seen.len())
                    .filter(|&k| t.seen[k] > 0)
                    .map(|k| {
                        json!({"range_m": bin_name(k), "seen": t.seen[k], "detected": t.detected[k]})
                    })
                    .collect();
                json!({"id": id, "bins": bins})
            })
            .collect();
        let abs: Vec<f64> = self.elevation_errors_m.iter().map(|e| e.abs()).collect();
        let water = (self.water_frames > 0).then(|| {
            json!({
                "frames": self.water_frames,
                "unscored_masks": self.unscored_masks,
                "detection_by_range": by_range,
                "detection_within_7m": self.ranges.rate_within(7.0).map(round4),
                "detection_within_10m": self.ranges.rate_within(10.0).map(round4),
                "bodies": bodies,
                "false_region_frames": self.false_frames,
                "false_region_frame_share": rate(self.false_frames, self.water_frames),
                "false_regions": self.false_regions.iter().map(|f| json!({
                    "time_s": round4(f.time_ns as f64 * 1e-9), "pixels": f.pixels,
                    "share_on_water": round4(f.share_on_water as f64),
                    "cue_pixels": f.cues, "mean_row": f.mean_row})).collect::<Vec<_>>(),
                "pixel_precision": rate(self.water_pixels_on_truth, self.water_pixels),
                "pixel_recall": rate(self.truth_pixels_found, self.truth_pixels),
                "map_water_cells": self.map_water_cells,
                "map_water_cells_on_water": rate(self.map_water_cells_on_body, self.map_water_cells),
                "map_water_cells_on_water_ins_corrected":
                    rate(self.map_water_cells_on_body_registered, self.map_water_cells),
                "map_water_relative_elevation_median_abs_error_m":
                    crate::session::percentile(&abs, 0.5).map(round4),
            })
        });
        let objects: Vec<_> = self
            .objects
            .iter()
            .filter(|(_, t)| t.observed > 0)
            .map(|(id, t)| {
                json!({"id": id, "class": messages::truth_class::name(t.class),
                       "observed_frames": t.observed, "detected_frames": t.detected,
                       "detected_share": rate(t.detected as u64, t.observed as u64),
                       "nearest_m": round4(t.nearest_m)})
            })
            .collect();
        // Without a scored object in view (the trail scenarios) precision and recall mean nothing.
        let hazard = (!objects.is_empty()).then(|| {
            json!({
                "maps": self.local_cells.maps,
                "objects": objects,
                "objects_detected_every_frame": self.objects.values()
                    .filter(|t| t.observed > 0 && t.detected == t.observed).count(),
                "cell_precision": self.local_cells.precision(),
                "cell_recall": self.local_cells.recall(),
                "hazard_cells": self.local_cells.hazard,
                "world_map": (self.world_cells.maps > 0).then(|| json!({
                    "maps": self.world_cells.maps,
                    "hazard_threshold": WORLD_HAZARD_THRESHOLD,
                    "cell_precision": self.world_cells.precision(),
                    "cell_recall": self.world_cells.recall(),
                    "hazard_cells_per_map":
                        round4(self.world_cells.hazard as f64 / self.world_cells.maps as f64),
                })),
            })
        });
        json!({"water": water, "hazard": hazard})
    }
}

/// Prints the figures of [`PerceptionEval::report`].
pub fn print(report: &serde_json::Value) {
    let f = |v: &serde_json::Value, scale: f64| {
        v.as_f64()
            .map_or("-".to_string(), |x| format!("{:.1}", x * scale))
    };
    let w = &report["water"];
    if w.is_object() {
        println!(
            "water: {} frames; false-region frames {} ({} %); pixel precision {} %, recall {} %; map water cells {} ({} % on water, {} % without the INS error; relative elevation median |err| {} m)",
            w["frames"],
            w["false_region_frames"],
            f(&w["false_region_frame_share"], 100.0),
            f(&w["pixel_precision"], 100.0),
            f(&w["pixel_recall"], 100.0),
            w["map_water_cells"],
            f(&w["map_water_cells_on_water"], 100.0),
            f(&w["map_water_cells_on_water_ins_corrected"], 100.0),
            w["map_water_relative_elevation_median_abs_error_m"]
                .as_f64()
                .map_or("-".into(), |v| format!("{v:.2}")),
        );
        let bins = w["detection_by_range"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        let line: Vec<String> = bins
            .iter()
            .filter(|b| b["seen"].as_u64().unwrap_or(0) > 0)
            .map(|b| {
                format!(
                    "{} m {}/{} ({} %)",
                    b["range_m"].as_str().unwrap_or(""),
                    b["detected"],
                    b["seen"],
                    f(&b["rate"], 100.0)
                )
            })
            .collect();
        println!("  bodies detected by range: {}", line.join(", "));
    }
    let h = &report["hazard"];
    if h.is_object() {
        let objects = h["objects"].as_array().cloned().unwrap_or_default();
        println!(
            "hazard map: {} maps; cell precision {} %, recall {} %; {} of {} observed objects detected in every frame",
            h["maps"],
            f(&h["cell_precision"], 100.0),
            f(&h["cell_recall"], 100.0),
            h["objects_detected_every_frame"],
            objects.len()
        );
        let wm = &h["world_map"];
        if wm.is_object() {
            println!(
                "world map: {} maps; cells >= {}: precision {} %, recall {} %, {} a map",
                wm["maps"],
                wm["hazard_threshold"],
                f(&wm["cell_precision"], 100.0),
                f(&wm["cell_recall"], 100.0),
                f(&wm["hazard_cells_per_map"], 1.0)
            );
        }
        for o in &objects {
            println!(
                "  {} {}: detected {}/{} frames, nearest {} m",
                o["class"].as_str().unwrap_or(""),
                o["id"],
                o["detected_frames"],
                o["observed_frames"],
                f(&o["nearest_m"], 1.0)
            );
        }
    }
}

/// Regions of fused water, labelled as the detector labels its regions (`water::regions::label`,
/// 8-connected): `labels` per pixel (0 = none), returns (label, pixels) per region.
fn label_components(
    mask: &[u8],
    width: usize,
    labels: &mut Vec<u32>,
    scratch: &mut Vec<u8>,
    parent: &mut Vec<u32>,
) -> Vec<(u32, u32)> {
    scratch.clear();
    scratch.extend(mask.iter().map(|m| m & water_cue::WATER));
    labels.clear();
    labels.resize(mask.len(), 0);
    let n = water::regions::label(scratch, width, mask.len() / width, labels, parent);
    let mut pixels = vec![0u32; n + 1];
    for &l in labels.iter() {
        pixels[l as usize] += 1;
    }
    (1..=n).map(|l| (l as u32, pixels[l])).collect()
}

/// Removes and returns the pending entries whose stamp has its truth, in stamp order.
fn take_ready<V, T>(pending: &mut BTreeMap<u64, V>, truth: &BTreeMap<u64, T>) -> Vec<(u64, V)> {
    let ready: Vec<u64> = pending
        .keys()
        .copied()
        .filter(|s| truth.contains_key(s))
        .collect();
    ready
        .into_iter()
        .filter_map(|s| pending.remove(&s).map(|v| (s, v)))
        .collect()
}

fn trim<V>(m: &mut BTreeMap<u64, V>) {
    while m.len() > PENDING {
        m.pop_first();
    }
}

fn round4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_are_eight_connected_water_pixels() {
        let w = water_cue::WATER;
        let c = water_cue::COLOR;
        // The diagonal joins the first two groups as in the detector; a cue without WATER is not
        // water.
        #[rustfmt::skip]
        let mask = [
            w, w, 0, 0, w,
            0, 0, w, c, 0,
            0, 0, w, w, 0,
        ];
        let (mut labels, mut binary, mut parent) = (Vec::new(), Vec::new(), Vec::new());
        let comps = label_components(&mask, 5, &mut labels, &mut binary, &mut parent);
        assert_eq!(comps, vec![(1, 5), (2, 1)]);
        assert_eq!(labels, vec![1, 1, 0, 0, 2, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0]);
    }
}
