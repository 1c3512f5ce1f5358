//! `usv topics`, `usv hz`, `usv echo`: look at a running set without disturbing it. The tools add one
//! subscriber (topics reserve slots for them) and never publish.

use messages::iceoryx2::prelude::*;
use messages::summary::Inspect;
use messages::{iceoryx2, topics};
use runtime::{Ports, Receive, Subscriber};
use serde_json::json;
use std::fmt::Debug;
use std::time::{Duration, Instant};

const POLL: Duration = Duration::from_millis(2);

pub fn list_topics(json_out: bool) -> anyhow::Result<()> {
    let config = runtime::domain::config()?;
    let mut rows = Vec::new();
    iceoryx2::prelude::ipc::Service::list(&config, |details| {
        let s = &details.static_details;
        if let iceoryx2::service::static_config::messaging_pattern::MessagingPattern::PublishSubscribe(
            ps,
        ) = s.messaging_pattern()
        {
            let t = ps.message_type_details();
            let nodes = details.dynamic_details.as_ref().map_or(0, |d| d.nodes.len());
            rows.push((
                s.name().as_str().to_string(),
                t.user_header.type_name().to_string(),
                t.payload.type_name().to_string(),
                nodes,
            ));
        }
        CallbackProgression::Continue
    })
    .map_err(|e| anyhow::anyhow!("cannot list services: {e:?}"))?;
    rows.sort();
    for (name, header, payload, nodes) in &rows {
        let known = topics::ALL
            .iter()
            .find(|t| t.name == name)
            .map_or("", |t| t.payload);
        if json_out {
            println!(
                "{}",
                json!({"topic": name, "message": known, "user_header": header, "payload": payload, "nodes": nodes})
            );
        } else {
            println!("{name:<34} {known:<16} nodes={nodes:<3} payload={payload} header={header}");
        }
    }
    if rows.is_empty() && !json_out {
        println!("no topics in this domain");
    }
    Ok(())
}

fn unknown_topic(name: &str) -> anyhow::Error {
    let names: Vec<_> = topics::ALL.iter().map(|t| t.name).collect();
    anyhow::anyhow!("unknown topic '{name}'; known topics: {}", names.join(", "))
}

/// `usv hz`: message rate from header stamps (sensor time), plus arrival rate.
pub fn hz(name: &str, duration: Option<f64>, json_out: bool) -> anyhow::Result<()> {
    let node = runtime::tool_node("usv-hz")?;
    messages::with_topic!(name, t => {
        let sub = t.subscriber(&node)?;
        hz_on(&sub, name, duration, json_out)
    })
    .unwrap_or_else(|| Err(unknown_topic(name)))
}

fn hz_on<P: ?Sized + IceoryxSend + Debug, H: ZeroCopySend + Debug + Inspect<P>>(
    sub: &Subscriber<P, H>,
    name: &str,
    duration: Option<f64>,
    json_out: bool,
) -> anyhow::Result<()>
where
    Subscriber<P, H>: Receive<P, H>,
{
    let shutdown = runtime::Shutdown::install()?;
    let start = Instant::now();
    let end = duration.map(|d| start + Duration::from_secs_f64(d));
    let (mut count, mut first, mut last) = (0u64, None::<u64>, 0u64);
    let mut window_start = (Instant::now(), 0u64, None::<u64>);
    let mut last_print = Instant::now();
    while !shutdown.requested() && end.is_none_or(|e| Instant::now() < e) {
        while let Some(stamp) = sub.receive_with(|h, p| h.header(p).stamp_ns)? {
            count += 1;
            first.get_or_insert(stamp);
            last = stamp;
            window_start.2.get_or_insert(stamp);
        }
        if !json_out && last_print.elapsed() >= Duration::from_secs(1) {
            let (t0, n0, s0) = window_start;
            let n = count - n0;
            let stamp_rate = s0
                .filter(|&s0| last > s0 && n > 1)
                .map(|s0| (n - 1) as f64 / ((last - s0) as f64 * 1e-9));
            println!(
                "{name}: {} (stamps)  {:.2} Hz (arrival)  total {count}",
                stamp_rate.map_or("-".into(), |r| format!("{r:.2} Hz")),
                n as f64 / t0.elapsed().as_secs_f64()
            );
            window_start = (Instant::now(), count, None);
            last_print = Instant::now();
        }
        std::thread::sleep(POLL);
    }
    let rate = first
        .filter(|&f| last > f && count > 1)
        .map(|f| (count - 1) as f64 / ((last - f) as f64 * 1e-9));
    if json_out {
        println!(
            "{}",
            json!({"topic": name, "messages": count, "rate_hz": rate, "seconds": start.elapsed().as_secs_f64()})
        );
    }
    Ok(())
}

/// `usv echo`: one summary line per message.
pub fn echo(name: &str, count: Option<u64>) -> anyhow::Result<()> {
    let node = runtime::tool_node("usv-echo")?;
    messages::with_topic!(name, t => {
        let sub = t.subscriber(&node)?;
        echo_on(&sub, count)
    })
    .unwrap_or_else(|| Err(unknown_topic(name)))
}

fn echo_on<P: ?Sized + IceoryxSend + Debug, H: ZeroCopySend + Debug + Inspect<P>>(
    sub: &Subscriber<P, H>,
    count: Option<u64>,
) -> anyhow::Result<()>
where
    Subscriber<P, H>: Receive<P, H>,
{
    let shutdown = runtime::Shutdown::install()?;
    let mut seen = 0;
    while !shutdown.requested() && count.is_none_or(|c| seen < c) {
        while let Some(line) = sub.receive_with(|h, p| h.summary(p))? {
            println!("{line}");
            seen += 1;
            if count.is_some_and(|c| seen >= c) {
                break;
            }
        }
        std::thread::sleep(POLL);
    }
    Ok(())
}
