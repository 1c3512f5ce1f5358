//! `sequencer run --config FILE [--mission FILE]`: the sequencer service; `sequencer bench`: the
//! arc and cycle timings (`usv bench arcs`).
//!
//! Subscribes the world map, the contact list and the INS; publishes one `ActuatorCommand` and one
//! `SequencerStatus` per cycle. A cycle runs on every world map, also on every INS sample with
//! `cycle_on = "ins"`, and when an input misses its deadline, so a stop goes out even when everything
//! fell silent. The command's stamp is the newest input stamp used.
//! The world-map stamp is the primary input reported in the heartbeat (lock-step sources pace on it).
//! Missions arrive on the request-response service `usv/control/mission`, polled on a tick inside the
//! same wait loop (iceoryx2 request-response has no event to wait on).

use anyhow::Context;
use messages::iceoryx2::prelude::*;
use messages::{iceoryx2, topics, MissionCommand, MissionReply, MAX_MISSION_TEXT};
use runtime::{Service, Wake};
use sequencer::{watchdog, CycleOn, Sequencer};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(clap::Parser)]
#[command(
    name = "sequencer",
    version,
    about = "Mission sequencer, avoidance and control"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Run as the sequencer service of a process set.
    Run {
        /// Service configuration (TOML); see `sequencer::Config`.
        #[arg(long)]
        config: PathBuf,
        /// Mission to start with (TOML); more can be loaded with `usv mission load`.
        #[arg(long)]
        mission: Option<PathBuf>,
    },
    /// Arc evaluation and whole-cycle timings (`usv bench arcs`).
    Bench {
        /// Fewer iterations (a smoke run).
        #[arg(long)]
        quick: bool,
    },
}

fn main() -> ExitCode {
    let cli = <Cli as clap::Parser>::parse();
    let result = match cli.command {
        Command::Run { config, mission } => run(config, mission),
        Command::Bench { quick } => {
            for (name, value, unit) in sequencer::bench::run(quick) {
                println!("{name:<72} {value:>10.2} {unit}");
            }
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

type MissionServer =
    iceoryx2::port::server::Server<ipc::Service, MissionCommand, (), MissionReply, ()>;
type MissionFactory = iceoryx2::service::port_factory::request_response::PortFactory<
    ipc::Service,
    MissionCommand,
    (),
    MissionReply,
    (),
>;

/// Requests answered per tick at most: an operator tool, not a data stream.
const REQUESTS_PER_TICK: usize = 4;

fn open_server(node: &Node<ipc::Service>) -> anyhow::Result<(MissionFactory, MissionServer)> {
    let name: ServiceName = topics::MISSION_SERVICE
        .try_into()
        .map_err(|e| anyhow::anyhow!("invalid service name: {e:?}"))?;
    let factory = node
        .service_builder(&name)
        .request_response::<MissionCommand, MissionReply>()
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e:?}", topics::MISSION_SERVICE))?;
    let server = factory
        .server_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("cannot create mission server: {e:?}"))?;
    Ok((factory, server))
}

fn serve(server: &MissionServer, seq: &mut Sequencer) -> anyhow::Result<()> {
    for _ in 0..REQUESTS_PER_TICK {
        let Some(request) = server
            .receive()
            .map_err(|e| anyhow::anyhow!("mission service receive failed: {e:?}"))?
        else {
            break;
        };
        let cmd = request.payload();
        let len = (cmd.text_len as usize).min(MAX_MISSION_TEXT);
        let reply = seq.request(cmd.action, &cmd.text[..len]);
        if reply.accepted == 1 {
            tracing::info!("mission request {}: {}", cmd.action, reply.message);
        } else {
            tracing::warn!("mission request {} refused: {}", cmd.action, reply.message);
        }
        if let Err(e) = request.send_copy(reply) {
            tracing::warn!("mission reply not sent: {e:?}");
        }
    }
    Ok(())
}

fn run(config: PathBuf, mission: Option<PathBuf>) -> anyhow::Result<()> {
    let cfg: sequencer::Config = runtime::config::load(&config)?;
    let mut seq = Sequencer::new(cfg.clone())
        .with_context(|| format!("configuration {}", config.display()))?;
    if let Some(path) = &mission {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read mission {}", path.display()))?;
        let message = seq
            .load_mission(&text)
            .with_context(|| format!("mission {}", path.display()))?;
        tracing::info!("{message}");
    }

    let mut service = Service::start("sequencer")?;
    let maps = service.subscriber(&topics::WORLD_MAP)?;
    let ins = service.subscriber(&topics::INS)?;
    let contacts = service.subscriber(&topics::CONTACTS)?;
    let mut commands = service.publisher(&topics::ACTUATOR_COMMAND)?;
    let mut statuses = service.publisher(&topics::SEQUENCER_STATUS)?;
    let (_factory, server) = open_server(service.node())?;
    let source = service.name().to_string();

    let deadline = Some(Duration::from_millis(cfg.input_deadline_ms));
    // Without a tracker in the set, a contacts deadline would only flag the service as degraded.
    let contacts_deadline = deadline.filter(|_| cfg.watchdog.require_contacts);
    let inputs = [
        maps.input(deadline),
        ins.input(deadline),
        contacts.input(contacts_deadline),
    ];
    const INPUT_BITS: [u32; 3] = [watchdog::MAP, watchdog::INS, watchdog::CONTACTS];
    let mut contacts_stamp = 0u64;
    let mut map_pending: Option<(u64, Instant)> = None;
    let contacts_wait = Duration::from_millis(cfg.contacts_wait_ms);
    tracing::info!(
        arcs = seq.arcs().arcs().len(),
        cycle_on = ?cfg.cycle_on,
        "sequencer ready"
    );
    service.run(
        &inputs,
        Some(Duration::from_millis(cfg.tick_ms.max(1))),
        |health, wake| {
            let started = Instant::now();
            let mut cycle = false;
            if let Wake::Deadline(i) = wake {
                seq.input_missed(INPUT_BITS[i]);
                cycle = true;
            }
            while let Some(sample) = ins.receive()? {
                match seq.on_ins(sample.payload()) {
                    // One cycle per sample, however the samples were batched into wake-ups: the
                    // controller's rate limits and integrators then see the same steps every run.
                    Ok(()) if cfg.cycle_on == CycleOn::Ins => {
                        run_cycle(&mut seq, &source, &mut commands, &mut statuses)?
                    }
                    Ok(()) => {}
                    // Stamp 0: an INS sample must not advance the map stamp lock-step sources read.
                    Err(e) => health.reject(0, &e.to_string()),
                }
            }
            if let Some(sample) = contacts.latest()? {
                contacts_stamp = contacts_stamp.max(sample.payload().hdr.stamp_ns);
                seq.on_contacts(sample.payload());
            }
            if let Some(sample) = maps.latest()? {
                let stamp = sample.user_header().hdr.stamp_ns;
                match seq.on_map(sample.user_header(), sample.payload()) {
                    Ok(()) => map_pending = Some((stamp, Instant::now())),
                    Err(e) => health.reject(stamp, &e.to_string()),
                }
            }
            // A new map gets a decision, so the command for a frame goes out before the frame is
            // reported done (lock-step sources apply it next). With a tracker in the set the decision
            // waits for the contacts of the same frame (the tracker reads the same map), so it does
            // not depend on which of the two was faster; a silent tracker delays it by at most
            // `contacts_wait`.
            let mut map_stamp = None;
            if let Some((stamp, since)) = map_pending {
                if !cfg.watchdog.require_contacts
                    || contacts_stamp >= stamp
                    || since.elapsed() >= contacts_wait
                {
                    map_pending = None;
                    map_stamp = Some(stamp);
                    cycle = true;
                }
            }
            if wake == Wake::Tick {
                serve(&server, &mut seq)?;
            }
            if cycle {
                run_cycle(&mut seq, &source, &mut commands, &mut statuses)?;
            }
            if let Some(stamp) = map_stamp {
                health.record(stamp, started);
            }
            Ok(())
        },
    )
}

/// One sequencer cycle: decide, then publish the command and the status.
fn run_cycle(
    seq: &mut Sequencer,
    source: &str,
    commands: &mut runtime::Publisher<messages::ActuatorCommand, ()>,
    statuses: &mut runtime::Publisher<messages::SequencerStatus, ()>,
) -> anyhow::Result<()> {
    let (mut command, mut status) = seq.cycle(source);
    command.hdr.seq = commands.next_seq();
    commands.publish(&command)?;
    status.hdr.seq = statuses.next_seq();
    statuses.publish(&status)?;
    Ok(())
}
