//! The world map state and its per-update steps: recenter (shift), decay, fuse, re-localize water,
//! write out.

use messages::{GridGeometry, InsState, LocalMapHeader, MapCell, Pose, WorldMapHeader};
use serde::Deserialize;

/// Longest cost history a cell keeps (the paper averages N = 3).
pub const MAX_COST_HISTORY: usize = 8;

/// Mapper configuration (`mapper run --config FILE`; every field has a default).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// Edge of the square world map (m); the vessel sits at its centre.
    pub size_m: f64,
    /// Cell edge (m).
    pub resolution_m: f64,
    /// Number of most recent observations averaged per cell, cost and hazard alike (the paper's
    /// N = 3). A cell observed fewer times counts the missing observations as clear water, so a
    /// single-frame stereo mismatch never reaches full hazard: it takes N frames of evidence.
    pub cost_history: usize,
    /// Local maps in which a cell must have been water before it is output as confirmed water.
    pub water_confirm: u8,
    /// Move earlier water placements when a newer elevation estimate of the same water body arrives.
    pub relocalize_water: bool,
    /// Water cells closer than this (m) belong to one water body: gaps left by moved placements
    /// must not split a body into parts that no longer get its elevation updates.
    pub water_link_m: f64,
    /// Height of the stereo heads above the vessel origin (m): the apex of the rays water was
    /// placed along.
    pub camera_height_m: f64,
    /// Half-life of hazard evidence in stream time (s).
    pub hazard_half_life_s: f64,
    /// Fraction of the gap closed when a cell is observed with less hazard than the map holds.
    pub hazard_clear_gain: f64,
    /// Largest gap (ms) between a local map's stamp and the INS samples around it for the INS to
    /// re-register the map; beyond it the local map's own pose is used.
    pub ins_max_gap_ms: u64,
    /// Longest expected gap between local maps before the heartbeat reports it (ms).
    pub input_deadline_ms: u64,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            size_m: 100.0,
            resolution_m: 0.5,
            cost_history: 3,
            water_confirm: 2,
            relocalize_water: true,
            water_link_m: 2.0,
            camera_height_m: 2.9,
            hazard_half_life_s: 1.0,
            hazard_clear_gain: 0.5,
            ins_max_gap_ms: 200,
            input_deadline_ms: 1000,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MapError {
    #[error("invalid mapper configuration: {0}")]
    Config(String),
    #[error("local map {seq}: {count} cells for a {width}x{height} grid")]
    CellCount {
        seq: u64,
        count: usize,
        width: u32,
        height: u32,
    },
    #[error("local map {seq}: invalid geometry ({0})", seq = .1)]
    Geometry(&'static str, u64),
    #[error("local map {seq}: vessel pose is not finite")]
    Pose { seq: u64 },
}

/// Per-cell state besides water.
#[derive(Debug, Clone, Copy)]
struct Cell {
    /// Hazard probability 0..=1, decayed to the newest stamp.
    hazard: f32,
    costs: [u8; MAX_COST_HISTORY],
    /// The local maps' hazards of the same observations as `costs`.
    hazards: [u8; MAX_COST_HISTORY],
    cost_len: u8,
    cost_head: u8,
    /// Observations of the cell in the local map of update `observed_update` (see `write`).
    observed: u8,
    observed_update: u32,
    max_height_cm: i16,
    elevation_cm: i16,
}

impl Default for Cell {
    fn default() -> Self {
        Self {
            hazard: 0.0,
            costs: [0; MAX_COST_HISTORY],
            hazards: [0; MAX_COST_HISTORY],
            cost_len: 0,
            cost_head: 0,
            observed: 0,
            observed_update: 0,
            max_height_cm: 0,
            elevation_cm: 0,
        }
    }
}

/// Water placement of a cell: where it was seen from and with which elevation, so a better elevation
/// estimate can move it along the same ray.
#[derive(Debug, Clone, Copy, Default)]
struct Water {
    /// Local maps that placed water here (saturating); 0 = no water.
    hits: u8,
    /// Update number of the newest placement.
    fresh: u32,
    /// Elevation (cm) the placement used.
    elev_cm: i16,
    /// Camera position (ENU) the water was seen from.
    obs: [f32; 3],
    /// Where the placement lies now (ENU, not snapped to the cell) and its half-length along the
    /// ray: kept continuous so that repeated moves do not creep by a cell each time.
    pos: [f32; 2],
    half: f32,
    /// Water body id (0 = not yet assigned); see [`Bodies`].
    body: u8,
}

/// Water bodies: ids persist across updates so that a body's placements all take its newest
/// elevation even after gaps separate them. Slot 0 is "none"; ids are recycled when a body has
/// no cells left, and the last slot is shared when all are taken.
const MAX_BODIES: usize = 256;

struct Bodies {
    used: [bool; MAX_BODIES],
    alias: [u8; MAX_BODIES],
    sum: [i64; MAX_BODIES],
    fresh: [i64; MAX_BODIES],
    cells: [u32; MAX_BODIES],
}

impl Bodies {
    fn new() -> Self {
        Self {
            used: [false; MAX_BODIES],
            alias: std::array::from_fn(|k| k as u8),
            sum: [0; MAX_BODIES],
            fresh: [0; MAX_BODIES],
            cells: [0; MAX_BODIES],
        }
    }

    fn resolve(&self, mut id: u8) -> u8 {
        while self.alias[id as usize] != id {
            id = self.alias[id as usize];
        }
        id
    }

    fn allocate(&mut self) -> u8 {
        let k = (1..MAX_BODIES)
            .find(|&k| !self.used[k])
            .unwrap_or(MAX_BODIES - 1);
        self.used[k] = true;
        k as u8
    }
}

/// Latest INS positions, for re-registering local maps at their frame stamps.
const INS_RING: usize = 64;

/// The vessel-centred world map.
pub struct WorldMapper {
    cfg: Config,
    w: usize,
    h: usize,
    res: f64,
    /// Global index of cell (0, 0): global cell (i, j) covers [i*res, (i+1)*res) east and north.
    origin: [i64; 2],
    cells: Vec<Cell>,
    water: Vec<Water>,
    water_scratch: Vec<Water>,
    bodies: Bodies,
    /// Update number per cell when it was last labelled (component search without clearing).
    label: Vec<u32>,
    stack: Vec<u32>,
    component: Vec<u32>,
    ins: [(u64, [f64; 3]); INS_RING],
    ins_len: usize,
    ins_head: usize,
    newest_stamp: u64,
    decay_stamp: Option<u64>,
    vessel: Pose,
    fused: u64,
    update: u32,
    centred: bool,
}

impl WorldMapper {
    pub fn new(cfg: Config) -> Result<Self, MapError> {
        let bad = |m: &str| Err(MapError::Config(m.to_string()));
        if !(cfg.resolution_m.is_finite() && cfg.resolution_m > 0.0) {
            return bad("resolution_m must be > 0");
        }
        if !(cfg.size_m.is_finite() && cfg.size_m >= 2.0 * cfg.resolution_m) {
            return bad("size_m must be at least two cells");
        }
        let n = (cfg.size_m / cfg.resolution_m).round() as usize;
        if n > 4096 {
            return bad("size_m / resolution_m must be at most 4096 cells");
        }
        if cfg.cost_history == 0 || cfg.cost_history > MAX_COST_HISTORY {
            return bad("cost_history must be 1..=8");
        }
        if cfg.water_confirm == 0 {
            return bad("water_confirm must be >= 1");
        }
        if !(cfg.hazard_half_life_s.is_finite() && cfg.hazard_half_life_s > 0.0) {
            return bad("hazard_half_life_s must be > 0");
        }
        if !(0.0..=1.0).contains(&cfg.hazard_clear_gain) {
            return bad("hazard_clear_gain must be within 0..=1");
        }
        if !(cfg.water_link_m.is_finite() && (0.0..=20.0).contains(&cfg.water_link_m)) {
            return bad("water_link_m must be within 0..=20");
        }
        if !cfg.camera_height_m.is_finite() {
            return bad("camera_height_m must be finite");
        }
        let cells = n * n;
        Ok(Self {
            w: n,
            h: n,
            res: cfg.resolution_m,
            origin: [-(n as i64) / 2, -(n as i64) / 2],
            cells: vec![Cell::default(); cells],
            water: vec![Water::default(); cells],
            water_scratch: vec![Water::default(); cells],
            bodies: Bodies::new(),
            label: vec![0; cells],
            stack: Vec::with_capacity(cells),
            component: Vec::with_capacity(cells),
            ins: [(0, [0.0; 3]); INS_RING],
            ins_len: 0,
            ins_head: 0,
            newest_stamp: 0,
            decay_stamp: None,
            vessel: Pose::default(),
            fused: 0,
            update: 0,
            centred: false,
            cfg,
        })
    }

    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// Output grid geometry (ENU-aligned, centre on a cell corner within half a cell of the vessel).
    pub fn geometry(&self) -> GridGeometry {
        GridGeometry {
            width: self.w as u32,
            height: self.h as u32,
            resolution_m: self.res,
            center: [
                (self.origin[0] as f64 + self.w as f64 / 2.0) * self.res,
                (self.origin[1] as f64 + self.h as f64 / 2.0) * self.res,
            ],
        }
    }

    /// Header of the map as of the newest fused local map (`source` names the publisher).
    pub fn header(&self, seq: u64, source: &str) -> WorldMapHeader {
        WorldMapHeader {
            hdr: messages::Header::new(seq, self.newest_stamp, source),
            grid: self.geometry(),
            vessel: self.vessel,
            fused: self.fused,
        }
    }

    /// Local maps fused so far.
    pub fn fused(&self) -> u64 {
        self.fused
    }

    /// Remembers an INS sample for re-registering local maps. Invalid samples are refused.
    pub fn on_ins(&mut self, ins: &InsState) -> Result<(), &'static str> {
        ins.validate()?;
        self.ins[self.ins_head] = (ins.hdr.stamp_ns, ins.pose.position);
        self.ins_head = (self.ins_head + 1) % INS_RING;
        self.ins_len = (self.ins_len + 1).min(INS_RING);
        Ok(())
    }

    /// INS position at `stamp`, interpolated between the two samples around it when both are within
    /// the configured gap.
    fn ins_position(&self, stamp: u64) -> Option<[f64; 3]> {
        let gap = self.cfg.ins_max_gap_ms * 1_000_000;
        let mut before: Option<(u64, [f64; 3])> = None;
        let mut after: Option<(u64, [f64; 3])> = None;
        for &(t, p) in &self.ins[..self.ins_len] {
            if t <= stamp && before.is_none_or(|b| t > b.0) {
                before = Some((t, p));
            }
            if t >= stamp && after.is_none_or(|a| t < a.0) {
                after = Some((t, p));
            }
        }
        match (before, after) {
            (Some((t0, p0)), Some((t1, p1))) if stamp - t0 <= gap && t1 - stamp <= gap => {
                if t1 == t0 {
                    return Some(p0);
                }
                let a = (stamp - t0) as f64 / (t1 - t0) as f64;
                Some(std::array::from_fn(|k| p0[k] + a * (p1[k] - p0[k])))
            }
            (Some((t0, p0)), None) if stamp - t0 <= gap => Some(p0),
            _ => None,
        }
    }

    /// Fuses one local map. On error the map is unchanged.
    pub fn fuse(&mut self, hdr: &LocalMapHeader, cells: &[MapCell]) -> Result<(), MapError> {
        let seq = hdr.hdr.seq;
        let g = hdr.grid;
        if cells.len() != g.cell_count() {
            return Err(MapError::CellCount {
                seq,
                count: cells.len(),
                width: g.width,
                height: g.height,
            });
        }
        if g.width == 0 || g.height == 0 {
            return Err(MapError::Geometry("empty grid", seq));
        }
        if !(g.resolution_m.is_finite() && g.resolution_m > 0.0) {
            return Err(MapError::Geometry("resolution must be > 0", seq));
        }
        if !(g.center[0].is_finite() && g.center[1].is_finite()) {
            return Err(MapError::Geometry("centre is not finite", seq));
        }
        let p = &hdr.vessel;
        let pose_ok = p.position.iter().all(|v| v.is_finite())
            && p.roll.is_finite()
            && p.pitch.is_finite()
            && p.yaw.is_finite();
        if !pose_ok {
            return Err(MapError::Pose { seq });
        }
        let stamp = hdr.hdr.stamp_ns;
        self.update = self.update.wrapping_add(1).max(1);

        // Georegistration: the INS position at the frame stamp moves the local grid with the vessel.
        let mut vessel = hdr.vessel;
        let mut center = g.center;
        if let Some(pos) = self.ins_position(stamp) {
            center[0] += pos[0] - vessel.position[0];
            center[1] += pos[1] - vessel.position[1];
            vessel.position = pos;
        }

        if stamp >= self.newest_stamp || !self.centred {
            self.recenter(vessel.position[0], vessel.position[1]);
            self.vessel = vessel;
        }
        self.decay_to(stamp);
        let local = GridGeometry { center, ..g };
        let placed_water = self.fuse_cells(&local, cells, &vessel);
        if self.cfg.relocalize_water && placed_water {
            self.relocalize_water();
        }
        self.newest_stamp = self.newest_stamp.max(stamp);
        self.fused += 1;
        Ok(())
    }

    /// Scrolls the map so that the vessel is in the centre cell.
    fn recenter(&mut self, east: f64, north: f64) {
        let target = [
            (east / self.res).floor() as i64 - self.w as i64 / 2,
            (north / self.res).floor() as i64 - self.h as i64 / 2,
        ];
        if !self.centred {
            self.origin = target;
            self.centred = true;
            return;
        }
        let dx = target[0] - self.origin[0];
        let dy = target[1] - self.origin[1];
        if dx == 0 && dy == 0 {
            return;
        }
        shift(&mut self.cells, self.w, self.h, dx, dy);
        shift(&mut self.water, self.w, self.h, dx, dy);
        self.origin = target;
    }

    /// Decays hazard evidence to `stamp` (stream time; late frames of another head do not decay).
    fn decay_to(&mut self, stamp: u64) {
        let Some(prev) = self.decay_stamp else {
            self.decay_stamp = Some(stamp);
            return;
        };
        if stamp <= prev {
            return;
        }
        let dt = (stamp - prev) as f64 * 1e-9;
        let f = 0.5f64.powf(dt / self.cfg.hazard_half_life_s) as f32;
        // Below half a quantum of the output the evidence is gone.
        const FLOOR: f32 = 0.5 / 255.0;
        for c in &mut self.cells {
            let v = c.hazard * f;
            c.hazard = if v < FLOOR { 0.0 } else { v };
        }
        self.decay_stamp = Some(stamp);
    }

    /// Samples the local map at each world cell centre inside it (nearest neighbour, so any local
    /// resolution works) and fuses what it observed. Returns whether any water was placed.
    fn fuse_cells(&mut self, local: &GridGeometry, cells: &[MapCell], vessel: &Pose) -> bool {
        let lr = local.resolution_m;
        let (lw, lh) = (local.width as f64, local.height as f64);
        let west = local.center[0] - lw / 2.0 * lr;
        let south = local.center[1] - lh / 2.0 * lr;
        // World cells whose centres can fall inside the local grid.
        let c0 = ((west / self.res).floor() as i64 - self.origin[0]).max(0);
        let c1 = (((west + lw * lr) / self.res).ceil() as i64 - self.origin[0]).min(self.w as i64);
        let r0 = ((south / self.res).floor() as i64 - self.origin[1]).max(0);
        let r1 = (((south + lh * lr) / self.res).ceil() as i64 - self.origin[1]).min(self.h as i64);
        let gain = self.cfg.hazard_clear_gain as f32;
        let mut placed_water = false;
        let hist = self.cfg.cost_history as u8;
        let obs = [
            vessel.position[0] as f32,
            vessel.position[1] as f32,
            (vessel.position[2] + self.cfg.camera_height_m) as f32,
        ];
        for row in r0..r1 {
            let y = (self.origin[1] + row) as f64 * self.res + 0.5 * self.res;
            let lrow = ((y - south) / lr).floor();
            if lrow < 0.0 || lrow >= lh {
                continue;
            }
            let lrow = lrow as usize;
            for col in c0..c1 {
                let x = (self.origin[0] + col) as f64 * self.res + 0.5 * self.res;
                let lcol = ((x - west) / lr).floor();
                if lcol < 0.0 || lcol >= lw {
                    continue;
                }
                let l = cells[lrow * local.width as usize + lcol as usize];
                let measured = l.observed > 0 || l.cost != MapCell::UNKNOWN_COST;
                if !measured && l.hazard == 0 && l.water == 0 {
                    continue;
                }
                let i = row as usize * self.w + col as usize;
                let c = &mut self.cells[i];
                if l.cost != MapCell::UNKNOWN_COST {
                    c.costs[c.cost_head as usize] = l.cost;
                    c.hazards[c.cost_head as usize] = l.hazard;
                    c.cost_head = (c.cost_head + 1) % hist;
                    c.cost_len = (c.cost_len + 1).min(hist);
                }
                // The confirmed hazard (mean of the last N observations) rises at once and falls
                // gradually, so one missed frame does not erase an obstacle.
                let pl = history_mean(&c.hazards, c.cost_len, hist) / 255.0;
                if pl >= c.hazard {
                    c.hazard = pl;
                } else if measured {
                    c.hazard += gain * (pl - c.hazard);
                }
                if l.observed > 0 {
                    c.max_height_cm = l.max_height_cm;
                    c.elevation_cm = l.elevation_cm;
                }
                // At least one: a cost without range points (the local map's memory) is an
                // observation too.
                c.observed = l.observed.max(1);
                c.observed_update = self.update;
                let wcell = &mut self.water[i];
                if l.water > 0 {
                    wcell.hits = wcell.hits.saturating_add(1);
                    wcell.fresh = self.update;
                    wcell.elev_cm = l.elevation_cm;
                    wcell.obs = obs;
                    wcell.pos = [x as f32, y as f32];
                    wcell.half = 0.5 * self.res as f32;
                    placed_water = true;
                } else if l.observed > 0 {
                    // Range data of something that is not water: any water placed here was misplaced.
                    wcell.hits = 0;
                }
            }
        }
        placed_water
    }

    /// Re-localizes water (paper section 4): every water body (water cells linked within
    /// `water_link_m`) that got a
    /// placement this update takes the new elevation estimate, and its older cells move along the
    /// rays they were seen along to where that elevation puts them.
    fn relocalize_water(&mut self) {
        let (w, h) = (self.w, self.h);
        let update = self.update;
        let link = ((self.cfg.water_link_m / self.res).round() as i64).max(1);
        let b = &mut self.bodies;
        b.sum.fill(0);
        b.fresh.fill(0);
        b.cells.fill(0);
        for (k, a) in b.alias.iter_mut().enumerate() {
            *a = k as u8;
        }
        // Pass 1: components; each takes the lowest body id among its cells (bodies that touch merge)
        // or a new one, and sums this update's elevations per body.
        for start in 0..w * h {
            if self.water[start].hits == 0 || self.label[start] == update {
                continue;
            }
            self.component.clear();
            self.stack.clear();
            self.stack.push(start as u32);
            self.label[start] = update;
            while let Some(i) = self.stack.pop() {
                self.component.push(i);
                let (x, y) = ((i as usize % w) as i64, (i as usize / w) as i64);
                for ny in (y - link).max(0)..(y + link + 1).min(h as i64) {
                    for nx in (x - link).max(0)..(x + link + 1).min(w as i64) {
                        let n = ny as usize * w + nx as usize;
                        if self.water[n].hits > 0 && self.label[n] != update {
                            self.label[n] = update;
                            self.stack.push(n as u32);
                        }
                    }
                }
            }
            let b = &mut self.bodies;
            let existing = self
                .component
                .iter()
                .map(|&i| b.resolve(self.water[i as usize].body))
                .filter(|&id| id != 0)
                .min();
            let id = match existing {
                Some(id) => id,
                None => b.allocate(),
            };
            for &i in &self.component {
                let c = &mut self.water[i as usize];
                let old = b.resolve(c.body);
                if old != 0 && old != id {
                    b.alias[old as usize] = id;
                }
                c.body = id;
                b.cells[id as usize] += 1;
                if c.fresh == update {
                    b.sum[id as usize] += c.elev_cm as i64;
                    b.fresh[id as usize] += 1;
                }
            }
        }
        // Pass 2: every cell of a body with new placements moves to the body's new elevation, even
        // when it is no longer next to them.
        self.water_scratch.fill(Water::default());
        for i in 0..w * h {
            let mut c = self.water[i];
            if c.hits == 0 {
                continue;
            }
            let id = self.bodies.resolve(c.body);
            c.body = id;
            let k = id as usize;
            let fresh = self.bodies.fresh[k];
            if fresh > 0 && c.fresh != update {
                let e = (self.bodies.sum[k] as f64 / fresh as f64).round() as i16;
                if c.elev_cm != e {
                    self.reproject(i, c, e);
                    continue;
                }
            }
            merge(&mut self.water_scratch[i], c);
        }
        let b = &mut self.bodies;
        for k in 1..MAX_BODIES {
            b.used[k] = b.cells[k] > 0 && b.alias[k] == k as u8;
        }
        std::mem::swap(&mut self.water, &mut self.water_scratch);
    }

    /// Moves water cell `i` (placed with `c.elev_cm`) to where elevation `e` puts it along the rays
    /// from its observer, covering the whole stretched radial span.
    fn reproject(&mut self, i: usize, c: Water, e: i16) {
        let z_old = c.obs[2] as f64 - c.elev_cm as f64 / 100.0;
        let z_new = c.obs[2] as f64 - e as f64 / 100.0;
        // A camera at or below the water surface gives no geometry: keep the cell.
        if z_old < 0.05 || z_new < 0.05 {
            merge(&mut self.water_scratch[i], Water { elev_cm: e, ..c });
            return;
        }
        let ratio = z_new / z_old;
        let (ox, oy) = (c.obs[0] as f64, c.obs[1] as f64);
        let (rx, ry) = (c.pos[0] as f64 - ox, c.pos[1] as f64 - oy);
        let d = rx.hypot(ry);
        if d < 1e-6 {
            merge(&mut self.water_scratch[i], Water { elev_cm: e, ..c });
            return;
        }
        let (ux, uy) = (rx / d, ry / d);
        // The placement spans [d - half, d + half] along the ray; it maps to that span times `ratio`.
        let half = c.half as f64;
        let near = ratio * (d - half).max(0.0);
        let far = ratio * (d + half);
        let steps = (((far - near) / (0.5 * self.res)).ceil() as usize).max(1);
        let moved = Water {
            elev_cm: e,
            pos: [(ox + ux * ratio * d) as f32, (oy + uy * ratio * d) as f32],
            half: (ratio * half) as f32,
            ..c
        };
        for s in 0..=steps {
            let t = near + (far - near) * s as f64 / steps as f64;
            let (x, y) = (ox + ux * t, oy + uy * t);
            let gc = (x / self.res).floor() as i64 - self.origin[0];
            let gr = (y / self.res).floor() as i64 - self.origin[1];
            if gc < 0 || gr < 0 || gc >= self.w as i64 || gr >= self.h as i64 {
                continue;
            }
            merge(
                &mut self.water_scratch[gr as usize * self.w + gc as usize],
                moved,
            );
        }
    }

    /// Writes the map as of the newest fused stamp into `out` (row-major from the south-west
    /// corner, `width * height` cells).
    pub fn write(&self, out: &mut [MapCell]) {
        assert_eq!(out.len(), self.w * self.h, "output slice size");
        let confirm = self.cfg.water_confirm;
        let history = self.cfg.cost_history as u8;
        for ((o, c), wc) in out.iter_mut().zip(&self.cells).zip(&self.water) {
            let cost = if c.cost_len == 0 {
                MapCell::UNKNOWN_COST
            } else {
                (history_mean(&c.costs, c.cost_len, history).round() as u32)
                    .min(MapCell::LETHAL_COST as u32) as u8
            };
            let water = if wc.hits >= confirm {
                2
            } else if wc.hits > 0 {
                1
            } else {
                0
            };
            *o = MapCell {
                hazard: (c.hazard * 255.0).round().clamp(0.0, 255.0) as u8,
                cost,
                water,
                // This cycle's observations, as in a local map: the sensors' coverage now, which
                // the tracker needs to tell an object out of view from one that is gone. A cell
                // ever observed has a known cost.
                observed: if c.observed_update == self.update {
                    c.observed
                } else {
                    0
                },
                max_height_cm: c.max_height_cm,
                elevation_cm: if water > 0 {
                    wc.elev_cm
                } else {
                    c.elevation_cm
                },
            };
        }
    }

    /// Convenience for tests and tools: the whole map in a new vector.
    pub fn snapshot(&self) -> Vec<MapCell> {
        let mut v = vec![MapCell::default(); self.w * self.h];
        self.write(&mut v);
        v
    }
}

/// Combines a water placement into a cell: the most hits and the newest placement win.
fn merge(dst: &mut Water, src: Water) {
    if dst.hits == 0 {
        *dst = src;
        return;
    }
    let hits = dst.hits.max(src.hits);
    if src.fresh > dst.fresh {
        *dst = src;
    }
    dst.hits = hits;
}

/// Shifts a row-major `w x h` grid so that the cell at (dx, dy) becomes (0, 0); vacated cells are
/// reset. In place (`copy_within`), no allocation.
/// Mean of a cell's last `history` observations, of which it has `len` (the rest count as 0).
fn history_mean(values: &[u8; MAX_COST_HISTORY], len: u8, history: u8) -> f32 {
    let sum: u32 = values[..len as usize].iter().map(|&v| v as u32).sum();
    sum as f32 / history.max(1) as f32
}

fn shift<T: Copy + Default>(buf: &mut [T], w: usize, h: usize, dx: i64, dy: i64) {
    if dx.unsigned_abs() as usize >= w || dy.unsigned_abs() as usize >= h {
        buf.fill(T::default());
        return;
    }
    let sy = dy.unsigned_abs() as usize;
    if dy > 0 {
        buf.copy_within(sy * w.., 0);
        buf[(h - sy) * w..].fill(T::default());
    } else if dy < 0 {
        buf.copy_within(..(h - sy) * w, sy * w);
        buf[..sy * w].fill(T::default());
    }
    let sx = dx.unsigned_abs() as usize;
    if sx > 0 {
        for row in buf.chunks_exact_mut(w) {
            if dx > 0 {
                row.copy_within(sx.., 0);
                row[w - sx..].fill(T::default());
            } else {
                row.copy_within(..w - sx, sx);
                row[..sx].fill(T::default());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_moves_content_and_clears_vacated_cells() {
        let (w, h) = (4, 3);
        let mut b: Vec<u32> = (1..=12).collect();
        shift(&mut b, w, h, 1, 1);
        assert_eq!(b, vec![6, 7, 8, 0, 10, 11, 12, 0, 0, 0, 0, 0]);
        let mut b: Vec<u32> = (1..=12).collect();
        shift(&mut b, w, h, -1, -1);
        assert_eq!(b, vec![0, 0, 0, 0, 0, 1, 2, 3, 0, 5, 6, 7]);
        let mut b: Vec<u32> = (1..=12).collect();
        shift(&mut b, w, h, 4, 0);
        assert!(b.iter().all(|&v| v == 0));
    }

    #[test]
    fn config_errors_are_reported() {
        let bad = Config {
            cost_history: 0,
            ..Config::default()
        };
        assert!(matches!(WorldMapper::new(bad), Err(MapError::Config(_))));
        let bad = Config {
            resolution_m: 0.0,
            ..Config::default()
        };
        assert!(WorldMapper::new(bad).is_err());
    }
}
