//! `usv`: run, inspect and measure the autonomy stack's process sets.

mod bench;
mod chaos;
mod child;
mod control;
mod demo;
mod eval;
mod eval_perception;
mod eval_tracking;
mod inspect;
mod launchfile;
mod mission;
mod observe;
mod overview;
mod pipeline;
mod regress;
mod retrack;
mod session;
mod supervisor;

use clap::{Parser, Subcommand};
use control::{Reply, Request};
use std::path::PathBuf;
use std::time::Duration;

#[derive(Parser)]
#[command(
    name = "usv",
    version,
    about = "Run, inspect and measure the USV autonomy stack"
)]
struct Cli {
    /// Domain of the process set (keeps sets on one machine apart); default: $USV_DOMAIN or the
    /// default domain.
    #[arg(long, global = true)]
    domain: Option<String>,
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run the demo: the whole stack closed loop on a simulated scenario, then a summary and a picture.
    Demo(demo::DemoArgs),
    /// Run scenarios lock-step through the stack and report metrics against ground truth.
    Eval(eval::EvalArgs),
    /// Write the process set of a simulated run (for `usv up`) without running it.
    Set(pipeline::SetArgs),
    /// Replay a short recording through every service and compare with committed expectations.
    Regress(regress::RegressArgs),
    /// Run the tracker again over a recording's world maps and score it against the recorded truth.
    Retrack(retrack::RetrackArgs),
    /// Start a process set from a launch file and supervise it until `usv down` or Ctrl-C.
    Up { set: PathBuf },
    /// Stop the running set: SIGTERM, grace period, SIGKILL, then sweep stale shared memory.
    Down,
    /// Show the services of the running set.
    Ps {
        #[arg(long)]
        json: bool,
    },
    /// Restart one service of the running set.
    Restart { service: String },
    /// Replace one service's program while the others keep running.
    Swap {
        service: String,
        /// The new program (a path, or a name next to `usv` or on PATH).
        #[arg(long = "exec")]
        program: String,
        /// Arguments of the new program.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// List the topics of the running set.
    Topics {
        #[arg(long)]
        json: bool,
    },
    /// Measure a topic's rate (from header stamps) without disturbing the set.
    Hz {
        topic: String,
        /// Stop after this many seconds (default: until Ctrl-C).
        #[arg(long)]
        duration: Option<f64>,
        /// Print one JSON summary at the end instead of a line per second.
        #[arg(long)]
        json: bool,
    },
    /// Print a one-line summary of every message on a topic.
    Echo {
        topic: String,
        /// Stop after this many messages.
        #[arg(long)]
        count: Option<u64>,
    },
    /// Record the topics of the running set to MCAP (runs the `recorder` program; see `recorder --help`).
    Record {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Replay an MCAP recording into the running set (runs `sensors replay`; see `sensors replay --help`).
    Replay {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Reproduce the project's performance figures on this machine.
    Bench {
        /// Which benchmark: ipc, recorder, sim, pipeline, stereo, hazard, water, mapper, tracker.
        name: String,
        /// One JSON object per line per figure.
        #[arg(long)]
        json: bool,
        /// Fewer samples (a smoke run, not for reporting).
        #[arg(long)]
        quick: bool,
    },
    /// The receiving side of `usv bench ipc` (started by it).
    #[command(hide = true)]
    BenchPeer {
        #[arg(long, value_enum)]
        wake: bench::ipc::Wake,
        #[arg(long)]
        size: usize,
        #[arg(long)]
        socket: Option<String>,
    },
    /// Load, pause, resume or abort the sequencer's mission, or ask what it is doing.
    Mission {
        #[command(subcommand)]
        action: mission::MissionCmd,
    },
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("usv: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    if let Some(domain) = &cli.domain {
        runtime::domain::validate(domain)?;
        // Children and the runtime read the domain from the environment.
        std::env::set_var(runtime::domain::DOMAIN_ENV, domain);
    }
    let domain = runtime::domain::current();
    let call =
        |request: Request| control::call(domain.as_deref(), &request, Duration::from_secs(30));
    match cli.command {
        Cmd::Up { set } => {
            let set = launchfile::ProcessSet::load(&set)?;
            supervisor::Supervisor::new(set, domain.clone()).run()
        }
        Cmd::Demo(args) => demo::run(args),
        Cmd::Eval(args) => eval::run(args),
        Cmd::Regress(args) => regress::run(args),
        Cmd::Retrack(args) => retrack::run(args),
        Cmd::Set(args) => pipeline::run_set(args),
        Cmd::Down => print_reply(call(Request::Down)?),
        Cmd::Ps { json } => match call(Request::Ps)? {
            Reply::Ps { set, services } if json => {
                println!("{}", serde_json::json!({"set": set, "services": services}));
                Ok(())
            }
            Reply::Ps { set, services } => {
                println!("set {set}");
                println!(
                    "{:<16} {:>8} {:<12} {:>8} {:>10} {:>9} {:>9}  last error",
                    "service", "pid", "state", "restarts", "heartbeat", "rate", "processed"
                );
                for s in services {
                    println!(
                        "{:<16} {:>8} {:<12} {:>8} {:>10} {:>9} {:>9}  {}",
                        s.name,
                        s.pid.map_or("-".into(), |p| p.to_string()),
                        s.state,
                        s.restarts,
                        s.heartbeat_age_ms.map_or("-".into(), |a| format!("{a} ms")),
                        s.input_rate_hz.map_or("-".into(), |r| format!("{r:.1} Hz")),
                        s.processed,
                        s.last_error
                    );
                }
                Ok(())
            }
            other => print_reply(other),
        },
        Cmd::Restart { service } => print_reply(call(Request::Restart { service })?),
        Cmd::Swap {
            service,
            program,
            args,
        } => {
            // Paths are relative to the caller, not to the supervisor.
            let program = if program.contains('/') {
                std::fs::canonicalize(&program)
                    .map_err(|e| anyhow::anyhow!("program '{program}': {e}"))?
                    .display()
                    .to_string()
            } else {
                program
            };
            print_reply(call(Request::Swap {
                service,
                program,
                args,
            })?)
        }
        Cmd::Record { args } => exec("recorder", &args),
        Cmd::Replay { args } => exec("sensors", &[vec!["replay".to_string()], args].concat()),
        Cmd::Topics { json } => inspect::list_topics(json),
        Cmd::Hz {
            topic,
            duration,
            json,
        } => inspect::hz(&topic, duration, json),
        Cmd::Echo { topic, count } => inspect::echo(&topic, count),
        Cmd::Bench { name, json, quick } => {
            // Benchmarks run in a domain of their own so they never meet a running set.
            std::env::set_var(
                runtime::domain::DOMAIN_ENV,
                format!("bench{}", std::process::id()),
            );
            if bench::run_service_bench(&name, quick)? {
                return Ok(());
            }
            let figures = match name.as_str() {
                "ipc" => bench::ipc::run(quick)?,
                "recorder" => bench::recorder(quick)?,
                "sim" => bench::sim::run(quick)?,
                "pipeline" => bench::pipeline::run(quick)?,
                other => anyhow::bail!(
                    "unknown benchmark '{other}'; available: {}",
                    bench::NAMES.join(", ")
                ),
            };
            if json {
                for f in &figures {
                    println!("{}", f.json_line(&name));
                }
            } else if name == "ipc" {
                bench::ipc::print_table(&figures);
            } else {
                bench::print_plain(&figures);
            }
            let config = runtime::domain::config()?;
            runtime::cleanup::sweep_dead_nodes(&config);
            if let Some(domain) = runtime::domain::current() {
                runtime::cleanup::remove_domain_leftovers(&domain)?;
            }
            Ok(())
        }
        Cmd::BenchPeer { wake, size, socket } => bench::ipc::peer(wake, size, socket.as_deref()),
        Cmd::Mission { action } => mission::run(action),
    }
}

/// Replaces this process with one of the stack's programs (found next to `usv` or on PATH), so it
/// gets signals and the exit status directly.
fn exec(program: &str, args: &[String]) -> anyhow::Result<()> {
    use std::os::unix::process::CommandExt;
    let path =
        launchfile::resolve_program(program, std::path::Path::new(".")).ok_or_else(|| {
            anyhow::anyhow!("the `{program}` program was not found next to usv or on PATH")
        })?;
    Err(std::process::Command::new(path).args(args).exec().into())
}

fn print_reply(reply: Reply) -> anyhow::Result<()> {
    match reply {
        Reply::Ok { message } => {
            println!("{message}");
            Ok(())
        }
        Reply::Error { message } => anyhow::bail!(message),
        Reply::Ps { .. } => anyhow::bail!("unexpected reply"),
    }
}
