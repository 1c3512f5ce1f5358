//! One-line summaries of messages for inspection tools: images and grids are summarized, never dumped.

use crate::*;

/// Implemented by a topic's user header type `H` for its payload `P`: where the message [`Header`] is,
/// and a one-line human summary.
pub trait Inspect<P: ?Sized> {
    fn header<'a>(&'a self, payload: &'a P) -> &'a Header;
    fn summary(&self, payload: &P) -> String;
}

fn prefix(h: &Header) -> String {
    format!(
        "seq={} stamp={:.3}s src={}",
        h.seq,
        h.stamp_ns as f64 * 1e-9,
        h.source
    )
}

fn mean<T: Copy + Into<f64>>(values: impl Iterator<Item = T>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v.into(), n + 1));
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

impl Inspect<[u8]> for StereoFrameHeader {
    fn header<'a>(&'a self, _: &'a [u8]) -> &'a Header {
        &self.hdr
    }
    fn summary(&self, payload: &[u8]) -> String {
        let encoding = self
            .encoding()
            .map_or("invalid".into(), |e| format!("{e:?}"));
        let brightness = match self.planes(payload) {
            Some((left, _)) => format!("left mean {:.1}", mean(left.iter().step_by(64).copied())),
            None => format!("BAD SIZE {} bytes", payload.len()),
        };
        format!(
            "{} head={} {}x{} {} {}",
            prefix(&self.hdr),
            self.head,
            self.width,
            self.height,
            encoding,
            brightness
        )
    }
}

impl Inspect<[f32]> for DisparityHeader {
    fn header<'a>(&'a self, _: &'a [f32]) -> &'a Header {
        &self.hdr
    }
    fn summary(&self, payload: &[f32]) -> String {
        let valid = payload.iter().filter(|d| d.is_finite()).count();
        format!(
            "{} frame={} head={} {}x{} valid={:.1}% plane={} height={:.2}m",
            prefix(&self.hdr),
            self.frame_seq,
            self.head,
            self.width,
            self.height,
            100.0 * valid as f64 / payload.len().max(1) as f64,
            if self.plane.valid != 0 { "ok" } else { "none" },
            self.plane.camera_height_m
        )
    }
}

impl Inspect<[f32]> for TruthImageHeader {
    fn header<'a>(&'a self, _: &'a [f32]) -> &'a Header {
        &self.hdr
    }
    fn summary(&self, payload: &[f32]) -> String {
        format!(
            "{} head={} {}x{} values={}",
            prefix(&self.hdr),
            self.head,
            self.width,
            self.height,
            payload.len()
        )
    }
}

fn grid_summary(h: &Header, grid: &GridGeometry, cells: &[MapCell]) -> String {
    let hazards = cells.iter().filter(|c| c.hazard >= 128).count();
    let water = cells.iter().filter(|c| c.water == 2).count();
    format!(
        "{} grid {}x{}@{:.2}m centre=({:.1},{:.1}) hazard cells={} water cells={}",
        prefix(h),
        grid.width,
        grid.height,
        grid.resolution_m,
        grid.center[0],
        grid.center[1],
        hazards,
        water
    )
}

impl Inspect<[MapCell]> for LocalMapHeader {
    fn header<'a>(&'a self, _: &'a [MapCell]) -> &'a Header {
        &self.hdr
    }
    fn summary(&self, payload: &[MapCell]) -> String {
        grid_summary(&self.hdr, &self.grid, payload)
    }
}

impl Inspect<[MapCell]> for WorldMapHeader {
    fn header<'a>(&'a self, _: &'a [MapCell]) -> &'a Header {
        &self.hdr
    }
    fn summary(&self, payload: &[MapCell]) -> String {
        grid_summary(&self.hdr, &self.grid, payload)
    }
}

impl Inspect<[u8]> for WaterMaskHeader {
    fn header<'a>(&'a self, _: &'a [u8]) -> &'a Header {
        &self.hdr
    }
    fn summary(&self, payload: &[u8]) -> String {
        let water = payload
            .iter()
            .filter(|&&b| b & water_cue::WATER != 0)
            .count();
        format!(
            "{} head={} {}x{} regions={} water={:.1}%",
            prefix(&self.hdr),
            self.head,
            self.width,
            self.height,
            self.regions,
            100.0 * water as f64 / payload.len().max(1) as f64
        )
    }
}

impl Inspect<InsState> for () {
    fn header<'a>(&'a self, p: &'a InsState) -> &'a Header {
        &p.hdr
    }
    fn summary(&self, p: &InsState) -> String {
        format!(
            "{} pos=({:.2},{:.2},{:.2}) yaw={:.1}deg speed={:.2}m/s",
            prefix(&p.hdr),
            p.pose.position[0],
            p.pose.position[1],
            p.pose.position[2],
            p.pose.yaw.to_degrees(),
            p.speed()
        )
    }
}

impl Inspect<GroundTruth> for () {
    fn header<'a>(&'a self, p: &'a GroundTruth) -> &'a Header {
        &p.hdr
    }
    fn summary(&self, p: &GroundTruth) -> String {
        format!(
            "{} own=({:.1},{:.1}) objects={} water={}",
            prefix(&p.hdr),
            p.own.pose.position[0],
            p.own.pose.position[1],
            p.object_count,
            p.water_count
        )
    }
}

impl Inspect<ContactList> for () {
    fn header<'a>(&'a self, p: &'a ContactList) -> &'a Header {
        &p.hdr
    }
    fn summary(&self, p: &ContactList) -> String {
        let mut s = format!("{} contacts={}", prefix(&p.hdr), p.count);
        for c in p.as_slice().iter().take(8) {
            s += &format!(
                " [#{} {} ({:.1},{:.1})]",
                c.id,
                contact_class::name(c.class),
                c.position[0],
                c.position[1]
            );
        }
        s
    }
}

impl Inspect<ActuatorCommand> for () {
    fn header<'a>(&'a self, p: &'a ActuatorCommand) -> &'a Header {
        &p.hdr
    }
    fn summary(&self, p: &ActuatorCommand) -> String {
        format!(
            "{} rudder={:.1}deg throttle={:.0}% mode={}",
            prefix(&p.hdr),
            p.rudder_rad.to_degrees(),
            p.throttle_pct,
            p.mode
        )
    }
}

impl Inspect<SequencerStatus> for () {
    fn header<'a>(&'a self, p: &'a SequencerStatus) -> &'a Header {
        &p.hdr
    }
    fn summary(&self, p: &SequencerStatus) -> String {
        format!(
            "{} mission={} step={} ({}) arc={} goal_dist={:.1}m stale={:#x}",
            prefix(&p.hdr),
            p.mission_name,
            p.step,
            p.step_name,
            p.chosen_arc,
            p.goal_distance_m,
            p.stale_inputs
        )
    }
}

impl Inspect<Heartbeat> for () {
    fn header<'a>(&'a self, p: &'a Heartbeat) -> &'a Header {
        &p.hdr
    }
    fn summary(&self, p: &Heartbeat) -> String {
        format!(
            "{} pid={} {} processed={} rejected={} errors={} last={}us max={}us last_input={:.3}s {}",
            prefix(&p.hdr),
            p.pid,
            service_state::name(p.state),
            p.processed,
            p.rejected,
            p.errors,
            p.last_processing_us,
            p.max_processing_us,
            p.last_input_stamp_ns as f64 * 1e-9,
            p.last_error
        )
    }
}
