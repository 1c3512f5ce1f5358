//! The Foxglove WebSocket protocol, subprotocol `foxglove.websocket.v1`: JSON text messages for
//! control (`serverInfo`, `advertise`, `status`, `subscribe`, `unsubscribe`) and binary message
//! data frames (`0x01 | u32 subscription id | u64 timestamp ns | payload`, little-endian).
//! Only what a viewer needs is implemented: no client publishing, parameters or services.

use serde::Deserialize;
use serde_json::json;
use views::Schema;

/// The WebSocket subprotocol the server selects.
pub const SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// Opcode of a binary message data frame.
pub const OP_MESSAGE_DATA: u8 = 0x01;
/// Bytes before the payload of a message data frame.
pub const DATA_PREFIX_LEN: usize = 1 + 4 + 8;

/// A channel as advertised: one Foxglove view of one topic (and head).
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    pub id: u32,
    pub topic: String,
    pub schema: Schema,
}

impl Channel {
    fn to_json(&self) -> serde_json::Value {
        json!({
            "id": self.id,
            "topic": self.topic,
            "encoding": views::MESSAGE_ENCODING,
            "schemaName": self.schema.name(),
            "schema": self.schema.json_schema(),
            "schemaEncoding": views::SCHEMA_ENCODING,
        })
    }
}

/// The first message a client receives.
pub fn server_info(name: &str, session_id: &str) -> String {
    json!({
        "op": "serverInfo",
        "name": name,
        "capabilities": [],
        "supportedEncodings": [],
        "metadata": {},
        "sessionId": session_id,
    })
    .to_string()
}

pub fn advertise<'a>(channels: impl IntoIterator<Item = &'a Channel>) -> String {
    let list: Vec<_> = channels.into_iter().map(Channel::to_json).collect();
    json!({"op": "advertise", "channels": list}).to_string()
}

/// Status levels.
pub const INFO: u8 = 0;
pub const WARNING: u8 = 1;
pub const ERROR: u8 = 2;

pub fn status(level: u8, message: &str) -> String {
    json!({"op": "status", "level": level, "message": message}).to_string()
}

/// A client request the server acts on.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    /// (subscription id, channel id) pairs.
    Subscribe(Vec<(u32, u32)>),
    Unsubscribe(Vec<u32>),
    /// A valid message of an operation this server does not offer.
    Unsupported(String),
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProtocolError {
    #[error("invalid client message: {0}")]
    Invalid(String),
}

#[derive(Deserialize)]
struct Op {
    op: String,
}

#[derive(Deserialize)]
struct Subscription {
    id: u32,
    #[serde(rename = "channelId")]
    channel_id: u32,
}

#[derive(Deserialize)]
struct Subscribe {
    subscriptions: Vec<Subscription>,
}

#[derive(Deserialize)]
struct Unsubscribe {
    #[serde(rename = "subscriptionIds")]
    subscription_ids: Vec<u32>,
}

fn invalid(e: serde_json::Error) -> ProtocolError {
    ProtocolError::Invalid(e.to_string())
}

/// Parses a text message from a client.
pub fn parse_request(text: &str) -> Result<Request, ProtocolError> {
    let op: Op = serde_json::from_str(text).map_err(invalid)?;
    Ok(match op.op.as_str() {
        "subscribe" => Request::Subscribe(
            serde_json::from_str::<Subscribe>(text)
                .map_err(invalid)?
                .subscriptions
                .into_iter()
                .map(|s| (s.id, s.channel_id))
                .collect(),
        ),
        "unsubscribe" => Request::Unsubscribe(
            serde_json::from_str::<Unsubscribe>(text)
                .map_err(invalid)?
                .subscription_ids,
        ),
        other => Request::Unsupported(other.to_string()),
    })
}

/// Writes the prefix of a message data frame into the first [`DATA_PREFIX_LEN`] bytes of `frame`.
pub fn write_data_prefix(frame: &mut [u8], subscription: u32, timestamp_ns: u64) {
    frame[0] = OP_MESSAGE_DATA;
    frame[1..5].copy_from_slice(&subscription.to_le_bytes());
    frame[5..13].copy_from_slice(&timestamp_ns.to_le_bytes());
}

/// Splits a message data frame into (subscription id, timestamp ns, payload).
pub fn parse_data(frame: &[u8]) -> Option<(u32, u64, &[u8])> {
    if frame.len() < DATA_PREFIX_LEN || frame[0] != OP_MESSAGE_DATA {
        return None;
    }
    let sub = u32::from_le_bytes(frame[1..5].try_into().ok()?);
    let ts = u64::from_le_bytes(frame[5..13].try_into().ok()?);
    Some((sub, ts, &frame[DATA_PREFIX_LEN..]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    #[test]
    fn advertise_carries_schema_and_encodings() {
        let c = Channel {
            id: 3,
            topic: "usv/sensors/ins/fix".into(),
            schema: Schema::LocationFix,
        };
        let v: Value = serde_json::from_str(&advertise([&c])).unwrap();
        assert_eq!(v["op"], "advertise");
        let ch = &v["channels"][0];
        assert_eq!(ch["id"], 3);
        assert_eq!(ch["encoding"], "json");
        assert_eq!(ch["schemaEncoding"], "jsonschema");
        assert_eq!(ch["schemaName"], "foxglove.LocationFix");
        let schema: Value = serde_json::from_str(ch["schema"].as_str().unwrap()).unwrap();
        assert_eq!(schema["title"], "foxglove.LocationFix");
        let info: Value = serde_json::from_str(&server_info("bridge", "1")).unwrap();
        assert_eq!(info["op"], "serverInfo");
        assert!(info["capabilities"].as_array().unwrap().is_empty());
    }

    #[test]
    fn requests_parse_and_bad_ones_are_errors() {
        assert_eq!(
            parse_request(
                r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":3},{"id":1,"channelId":5}]}"#
            ),
            Ok(Request::Subscribe(vec![(0, 3), (1, 5)]))
        );
        assert_eq!(
            parse_request(r#"{"op":"unsubscribe","subscriptionIds":[1]}"#),
            Ok(Request::Unsubscribe(vec![1]))
        );
        assert_eq!(
            parse_request(r#"{"op":"getParameters","parameterNames":[]}"#),
            Ok(Request::Unsupported("getParameters".into()))
        );
        assert!(parse_request("not json").is_err());
        assert!(
            parse_request(r#"{"op":"subscribe","subscriptions":[{"id":-1,"channelId":3}]}"#)
                .is_err()
        );
    }

    #[test]
    fn data_frame_round_trip() {
        let mut frame = vec![0u8; DATA_PREFIX_LEN + 2];
        frame[DATA_PREFIX_LEN..].copy_from_slice(b"{}");
        write_data_prefix(&mut frame, 7, 1_234_567_890_123);
        assert_eq!(frame[0], 1);
        assert_eq!(&frame[1..5], &[7, 0, 0, 0]);
        assert_eq!(parse_data(&frame), Some((7, 1_234_567_890_123, &b"{}"[..])));
        assert_eq!(parse_data(&frame[..5]), None);
    }
}
