//! `usv mission load <file> | pause | resume | abort | status`: the client of the sequencer's mission
//! service (iceoryx2 request-response on `usv/control/mission`). The sequencer validates a mission
//! before it replaces the running one; a refusal is printed and makes the command fail.

use anyhow::Context;
use messages::iceoryx2::prelude::*;
use messages::{mission_action, topics, MissionCommand, MissionReply, MAX_MISSION_TEXT};
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(clap::Subcommand)]
pub enum MissionCmd {
    /// Send a mission file (TOML) to the sequencer; it replaces the running mission if valid.
    Load { file: PathBuf },
    /// Hold the running mission (throttle 0, step timers stopped).
    Pause,
    /// Continue a paused mission.
    Resume,
    /// End the running mission.
    Abort,
    /// Print what the sequencer is doing.
    Status,
}

/// How long to look for a sequencer, and then for its answer.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(3);
const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

pub fn run(cmd: MissionCmd) -> anyhow::Result<()> {
    let (action, text) = match cmd {
        MissionCmd::Load { file } => (
            mission_action::LOAD,
            std::fs::read_to_string(&file)
                .with_context(|| format!("cannot read mission {}", file.display()))?,
        ),
        MissionCmd::Pause => (mission_action::PAUSE, String::new()),
        MissionCmd::Resume => (mission_action::RESUME, String::new()),
        MissionCmd::Abort => (mission_action::ABORT, String::new()),
        MissionCmd::Status => (mission_action::STATUS, String::new()),
    };
    anyhow::ensure!(
        text.len() <= MAX_MISSION_TEXT,
        "mission file has {} bytes; at most {MAX_MISSION_TEXT} fit in one request",
        text.len()
    );
    // Built on the heap: the request carries 16 KiB of text.
    let mut request = Box::new(MissionCommand {
        action,
        text_len: text.len() as u32,
        text: [0; MAX_MISSION_TEXT],
    });
    request.text[..text.len()].copy_from_slice(text.as_bytes());

    let reply = call(&request)?;
    anyhow::ensure!(reply.accepted == 1, "{}", reply.message);
    println!("{}", reply.message);
    Ok(())
}

fn call(request: &MissionCommand) -> anyhow::Result<MissionReply> {
    let node = runtime::tool_node(&format!("usv_mission_{}", std::process::id()))?;
    let name: ServiceName = topics::MISSION_SERVICE
        .try_into()
        .map_err(|e| anyhow::anyhow!("invalid service name: {e:?}"))?;
    let service = node
        .service_builder(&name)
        .request_response::<MissionCommand, MissionReply>()
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e:?}", topics::MISSION_SERVICE))?;
    let client = service
        .client_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("cannot create mission client: {e:?}"))?;
    let start = Instant::now();
    // A request sent before the client has seen the server goes nowhere: resend until it has.
    let pending = loop {
        let pending = client
            .send_copy(*request)
            .map_err(|e| anyhow::anyhow!("cannot send mission request: {e:?}"))?;
        if pending.number_of_server_connections() > 0 {
            break pending;
        }
        anyhow::ensure!(
            start.elapsed() < CONNECT_TIMEOUT,
            "no sequencer serves {} in domain {} (is the set up?)",
            topics::MISSION_SERVICE,
            runtime::domain::current().unwrap_or_else(|| "default".into())
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let start = Instant::now();
    while start.elapsed() < REPLY_TIMEOUT {
        if let Some(reply) = pending
            .receive()
            .map_err(|e| anyhow::anyhow!("cannot receive the sequencer's reply: {e:?}"))?
        {
            return Ok(*reply.payload());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    anyhow::bail!("the sequencer did not answer within {REPLY_TIMEOUT:?}")
}
