//! Runs the sequencer again over a recording's INS samples, contact lists and world maps, and shows
//! why it did what it did: per map in a window, the own pose, the replayed decision (mode, chosen
//! arc, rudder, throttle) against the recorded command, how many arcs the map blocks along their
//! length and within `arcs.near_m`, the map hazards that block an arc close in, and the contacts
//! nearby. A change to the sequencer can so be tried on the inputs of a closed-loop run in seconds
//! (until the changed commands would have turned the boat: the recording keeps the old course).
//!
//! ```text
//! cargo run --release -p sequencer --example recycle -- out/eval/cluttered_river-54/run.mcap \
//!     --from 66 --to 72
//! ```
//!
//! Times are seconds from the first INS sample. The mission is the `mission.toml` beside the
//! recording unless `--mission` names another.

use anyhow::Context;
use clap::Parser;
use messages::recording::{read_slice, read_value, split};
use messages::{
    topics, ActuatorCommand, ContactList, InsState, MapCell, SequencerStatus, WorldMapHeader,
};
use sequencer::{Config, Sequencer};
use std::path::PathBuf;

#[derive(Parser)]
struct Args {
    /// A recording with INS, contacts, world maps and actuator commands (`usv eval --record`).
    recording: PathBuf,
    /// Seconds to print.
    #[arg(long, default_value_t = 0.0)]
    from: f64,
    #[arg(long, default_value_t = f64::INFINITY)]
    to: f64,
    /// Sequencer settings.
    #[arg(long, default_value = "launch/sets/sequencer.toml")]
    config: PathBuf,
    /// Mission file (default: `mission.toml` beside the recording).
    #[arg(long)]
    mission: Option<PathBuf>,
    /// Contacts this close to the own boat are listed (m).
    #[arg(long, default_value_t = 25.0)]
    radius: f64,
    /// Hazards blocking an arc close in: at most this many, nearest first.
    #[arg(long, default_value_t = 8)]
    hazards: usize,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let cfg: Config = runtime::config::load(&args.config)?;
    let mut seq = Sequencer::new(cfg).context("sequencer configuration")?;
    let mission = args.mission.clone().unwrap_or_else(|| {
        args.recording
            .parent()
            .unwrap_or(std::path::Path::new("."))
            .join("mission.toml")
    });
    let text = std::fs::read_to_string(&mission)
        .with_context(|| format!("cannot read mission {}", mission.display()))?;
    seq.load_mission(&text)
        .with_context(|| format!("mission {}", mission.display()))?;

    let wanted = [
        topics::INS.name,
        topics::CONTACTS.name,
        topics::WORLD_MAP.name,
        topics::ACTUATOR_COMMAND.name,
    ];
    let rec = sensors::Recording::open(&args.recording)?;
    let topic_of: std::collections::BTreeMap<u16, String> =
        rec.channels().map(|c| (c.id, c.topic.clone())).collect();
    let mut t0 = None;
    let mut own: Option<InsState> = None;
    let mut contacts_stamp = 0u64;
    // A map waits for the contacts of its frame, as in the service.
    let mut pending: Option<(WorldMapHeader, Vec<MapCell>)> = None;
    let mut last: Option<(ActuatorCommand, SequencerStatus)> = None;
    let mut contacts = Box::<ContactList>::default();
    let (mut compared, mut same) = (0u64, 0u64);
    let mut hazards = Vec::new();
    for msg in rec.messages(0, |t| wanted.contains(&t)) {
        let msg = msg?;
        let topic = topic_of.get(&msg.channel).map_or("", String::as_str);
        let (header, payload) = split(&msg.data).context("corrupt framing")?;
        // SAFETY (all): the recorded types are plain numbers.
        if topic == topics::INS.name {
            let ins: InsState = unsafe { read_value(payload) }.context("short INS sample")?;
            t0.get_or_insert(ins.hdr.stamp_ns);
            if seq.on_ins(&ins).is_ok() {
                own = Some(ins);
                if seq.config().cycle_on == sequencer::CycleOn::Ins {
                    last = Some(seq.cycle("recycle"));
                }
            }
        } else if topic == topics::CONTACTS.name {
            *contacts = unsafe { read_value(payload) }.context("short contact list")?;
            contacts_stamp = contacts_stamp.max(contacts.hdr.stamp_ns);
            seq.on_contacts(&contacts);
        } else if topic == topics::WORLD_MAP.name {
            let header: WorldMapHeader =
                unsafe { read_value(header) }.context("short world-map header")?;
            let cells: Vec<MapCell> = unsafe { read_slice(payload) };
            seq.on_map(&header, &cells)
                .with_context(|| format!("world map at {} ns", header.hdr.stamp_ns))?;
            pending = Some((header, cells));
        } else {
            let recorded: ActuatorCommand =
                unsafe { read_value(payload) }.context("short actuator command")?;
            if let Some((cmd, _)) = &last {
                if cmd.hdr.stamp_ns == recorded.hdr.stamp_ns {
                    compared += 1;
                    same += u64::from(
                        cmd.rudder_rad == recorded.rudder_rad
                            && cmd.throttle_pct == recorded.throttle_pct
                            && cmd.mode == recorded.mode,
                    );
                }
            }
        }
        let ready = pending
            .as_ref()
            .is_some_and(|(h, _)| contacts_stamp >= h.hdr.stamp_ns);
        if !ready {
            continue;
        }
        let (map, cells) = pending.take().expect("checked above");
        let (cmd, status) = seq.cycle("recycle");
        last = Some((cmd, status));
        let t = (map.hdr.stamp_ns - t0.unwrap_or(0)) as f64 * 1e-9;
        if t < args.from || t > args.to {
            continue;
        }
        let Some(ins) = &own else { continue };
        // The obstacle offsets the sequencer took from this map, for the maps printed only.
        seq.arcs().collect_hazards(&map.grid, &cells, &mut hazards);
        print_cycle(
            &seq, &args, t, ins, &map, &hazards, &contacts, &cmd, &status,
        );
    }
    println!(
        "{same} of {compared} replayed commands equal the recorded ones (a difference is the \
         change under test, or an input order the replay does not reproduce)"
    );
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn print_cycle(
    seq: &Sequencer,
    args: &Args,
    t: f64,
    ins: &InsState,
    map: &WorldMapHeader,
    hazards: &[[f32; 2]],
    contacts: &ContactList,
    cmd: &ActuatorCommand,
    status: &SequencerStatus,
) {
    let arcs = seq.arcs();
    let position = [ins.pose.position[0], ins.pose.position[1]];
    let yaw = ins.pose.yaw;
    let speed = ins.velocity[0] * yaw.cos() + ins.velocity[1] * yaw.sin();
    let blocked = arcs.blocked(hazards, map.grid.center, position, yaw);
    println!(
        "{t:7.2} own ({:7.1},{:7.1}) yaw {:6.1} v {speed:5.2} | mode {} arc {:3} rudder {:6.1} \
         throttle {:6.1} | map blocks {} arcs, {} close in (of {}){}",
        position[0],
        position[1],
        yaw.to_degrees(),
        cmd.mode,
        status.chosen_arc,
        (cmd.rudder_rad as f64).to_degrees(),
        cmd.throttle_pct,
        blocked.mask.count_ones(),
        blocked.near.count_ones(),
        arcs.arcs().len(),
        if blocked.astern {
            ", lane astern blocked"
        } else {
            ""
        },
    );
    // Each hazard alone: the ones that block some arc within `near_m`.
    let mut close: Vec<([f64; 2], u32)> = hazards
        .iter()
        .filter_map(|h| {
            let b = arcs.blocked(std::slice::from_ref(h), map.grid.center, position, yaw);
            let at = [
                map.grid.center[0] + h[0] as f64,
                map.grid.center[1] + h[1] as f64,
            ];
            (b.near != 0).then_some((at, b.near.count_ones()))
        })
        .collect();
    let range = |p: [f64; 2]| (p[0] - position[0]).hypot(p[1] - position[1]);
    close.sort_by(|a, b| range(a.0).total_cmp(&range(b.0)));
    for (at, n) in close.iter().take(args.hazards) {
        println!(
            "          hazard ({:7.1},{:7.1}) {:5.1} m off blocks {n} arcs close in",
            at[0],
            at[1],
            range(*at)
        );
    }
    for c in contacts.as_slice() {
        let r = range([c.position[0], c.position[1]]);
        if r <= args.radius {
            println!(
                "          contact {} class {} confirmed {} coasting {} at ({:7.1},{:7.1}) {r:5.1} m \
                 off, {:4.1} m/s, {:.1} x {:.1} m, sigma {:.1} m, age {:.1} s",
                c.id,
                c.class,
                c.confirmed,
                c.coasting,
                c.position[0],
                c.position[1],
                c.velocity[0].hypot(c.velocity[1]),
                c.extent[0],
                c.extent[1],
                c.covariance[0].max(c.covariance[5]).max(0.0).sqrt(),
                c.age_s
            );
        }
    }
}
