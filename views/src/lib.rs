//! Foxglove well-known schemas (JSON encoding), so recordings and the live bridge show images, grids,
//! contacts, position and logs in Foxglove. One encoder for both: a recording and the live view of
//! the same data look the same. These channels are for viewing only; replay uses the raw channels.
//! Bytes fields (`data`) are base64 strings, as Foxglove expects for JSON messages.

use base64::Engine;
use messages::*;
use serde_json::{json, Value};
use std::collections::BTreeMap;

/// Schema encoding and message encoding of these channels.
pub const SCHEMA_ENCODING: &str = "jsonschema";
pub const MESSAGE_ENCODING: &str = "json";

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Schema {
    RawImage,
    Grid,
    SceneUpdate,
    LocationFix,
    FrameTransform,
    Log,
}

const TIME: &str =
    r#"{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}}"#;
const VEC3: &str = r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}}"#;
const QUAT: &str = r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}"#;

impl Schema {
    pub fn name(self) -> &'static str {
        match self {
            Self::RawImage => "foxglove.RawImage",
            Self::Grid => "foxglove.Grid",
            Self::SceneUpdate => "foxglove.SceneUpdate",
            Self::LocationFix => "foxglove.LocationFix",
            Self::FrameTransform => "foxglove.FrameTransform",
            Self::Log => "foxglove.Log",
        }
    }

    /// Channel topic suffix (`<topic>/<suffix>`).
    pub fn suffix(self) -> &'static str {
        match self {
            Self::RawImage => "image",
            Self::Grid => "grid",
            Self::SceneUpdate => "scene",
            Self::LocationFix => "fix",
            Self::FrameTransform => "tf",
            Self::Log => "log",
        }
    }

    /// The JSON schema (the fields this recorder writes).
    pub fn json_schema(self) -> String {
        let pose = format!(
            r#"{{"type":"object","properties":{{"position":{VEC3},"orientation":{QUAT}}}}}"#
        );
        let color = r#"{"type":"object","properties":{"r":{"type":"number"},"g":{"type":"number"},"b":{"type":"number"},"a":{"type":"number"}}}"#;
        let bytes = r#"{"type":"string","contentEncoding":"base64"}"#;
        let props = match self {
            Self::RawImage => format!(
                r#""timestamp":{TIME},"frame_id":{{"type":"string"}},"width":{{"type":"integer"}},"height":{{"type":"integer"}},"encoding":{{"type":"string"}},"step":{{"type":"integer"}},"data":{bytes}"#
            ),
            Self::Grid => format!(
                r#""timestamp":{TIME},"frame_id":{{"type":"string"}},"pose":{pose},"column_count":{{"type":"integer"}},"cell_size":{{"type":"object","properties":{{"x":{{"type":"number"}},"y":{{"type":"number"}}}}}},"row_stride":{{"type":"integer"}},"cell_stride":{{"type":"integer"}},"fields":{{"type":"array","items":{{"type":"object","properties":{{"name":{{"type":"string"}},"offset":{{"type":"integer"}},"type":{{"type":"integer"}}}}}}}},"data":{bytes}"#
            ),
            Self::SceneUpdate => format!(
                r#""deletions":{{"type":"array","items":{{"type":"object"}}}},"entities":{{"type":"array","items":{{"type":"object","properties":{{"timestamp":{TIME},"frame_id":{{"type":"string"}},"id":{{"type":"string"}},"lifetime":{TIME},"frame_locked":{{"type":"boolean"}},"cubes":{{"type":"array","items":{{"type":"object","properties":{{"pose":{pose},"size":{VEC3},"color":{color}}}}}}},"texts":{{"type":"array","items":{{"type":"object","properties":{{"pose":{pose},"billboard":{{"type":"boolean"}},"font_size":{{"type":"number"}},"color":{color},"text":{{"type":"string"}}}}}}}}}}}}}}"#
            ),
            Self::LocationFix => format!(
                r#""timestamp":{TIME},"frame_id":{{"type":"string"}},"latitude":{{"type":"number"}},"longitude":{{"type":"number"}},"altitude":{{"type":"number"}},"position_covariance":{{"type":"array","items":{{"type":"number"}}}},"position_covariance_type":{{"type":"integer"}}"#
            ),
            Self::FrameTransform => format!(
                r#""timestamp":{TIME},"parent_frame_id":{{"type":"string"}},"child_frame_id":{{"type":"string"}},"translation":{VEC3},"rotation":{QUAT}"#
            ),
            Self::Log => format!(
                r#""timestamp":{TIME},"level":{{"type":"integer"}},"message":{{"type":"string"}},"name":{{"type":"string"}},"file":{{"type":"string"}},"line":{{"type":"integer"}}"#
            ),
        };
        format!(
            r#"{{"title":"{}","type":"object","properties":{{{props}}}}}"#,
            self.name()
        )
    }
}

/// State kept across messages (for logs: what each service reported last).
#[derive(Default)]
pub struct ViewState {
    /// Service -> errors + rejected + missed deadlines seen in its previous heartbeat.
    problems: BTreeMap<String, u64>,
}

/// How a topic is shown in Foxglove, implemented by the topic's user header type for its payload.
pub trait View<P: ?Sized> {
    /// The Foxglove channels of this topic (none by default).
    fn schemas() -> &'static [Schema] {
        &[]
    }

    /// Appends the JSON message for `schema` to `out`; returns `false` when there is nothing to show.
    fn render(
        &self,
        _payload: &P,
        _schema: Schema,
        _state: &mut ViewState,
        _out: &mut Vec<u8>,
    ) -> bool {
        false
    }
}

fn time(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

/// Quaternion of roll, pitch, yaw (ZYX).
fn quaternion(roll: f64, pitch: f64, yaw: f64) -> Value {
    let (sr, cr) = (roll / 2.0).sin_cos();
    let (sp, cp) = (pitch / 2.0).sin_cos();
    let (sy, cy) = (yaw / 2.0).sin_cos();
    json!({
        "x": sr * cp * cy - cr * sp * sy,
        "y": cr * sp * cy + sr * cp * sy,
        "z": cr * cp * sy - sr * sp * cy,
        "w": cr * cp * cy + sr * sp * sy,
    })
}

fn pose(p: &Pose) -> Value {
    json!({
        "position": {"x": p.position[0], "y": p.position[1], "z": p.position[2]},
        "orientation": quaternion(p.roll, p.pitch, p.yaw),
    })
}

/// Appends `"data":"<base64>"}` (the closing brace of the message included) without building an
/// intermediate string: images are megabytes.
fn finish_with_data(out: &mut Vec<u8>, bytes: &[u8]) {
    out.extend_from_slice(b",\"data\":\"");
    let start = out.len();
    out.resize(
        start + base64::encoded_len(bytes.len(), true).unwrap_or(0),
        0,
    );
    let n = base64::engine::general_purpose::STANDARD
        .encode_slice(bytes, &mut out[start..])
        .unwrap_or(0);
    out.truncate(start + n);
    out.extend_from_slice(b"\"}");
}

/// Writes `value` (an object) without its closing brace, to be completed by `finish_with_data`.
fn open_object(out: &mut Vec<u8>, value: &Value) {
    let _ = serde_json::to_writer(&mut *out, value);
    out.pop();
}

fn write_json(out: &mut Vec<u8>, value: &Value) -> bool {
    serde_json::to_writer(out, value).is_ok()
}

impl View<[u8]> for StereoFrameHeader {
    fn schemas() -> &'static [Schema] {
        &[Schema::RawImage]
    }

    /// The left image.
    fn render(&self, payload: &[u8], _: Schema, _: &mut ViewState, out: &mut Vec<u8>) -> bool {
        let (Some(encoding), Some((left, _))) = (self.encoding(), self.planes(payload)) else {
            return false;
        };
        let name = match encoding {
            PixelEncoding::Mono8 => "mono8",
            PixelEncoding::Rgb8 => "rgb8",
        };
        open_object(
            out,
            &json!({
                "timestamp": time(self.hdr.stamp_ns),
                "frame_id": self.head.as_str(),
                "width": self.width,
                "height": self.height,
                "encoding": name,
                "step": self.stride,
            }),
        );
        finish_with_data(out, left);
        true
    }
}

/// Foxglove numeric field types.
const UINT8: u8 = 1;
const INT16: u8 = 4;

fn grid(h: &Header, g: &GridGeometry, cells: &[MapCell], out: &mut Vec<u8>) -> bool {
    if cells.len() != g.cell_count() {
        return false;
    }
    let size = std::mem::size_of::<MapCell>();
    let fields: Vec<Value> = [
        ("hazard", 0, UINT8),
        ("cost", 1, UINT8),
        ("water", 2, UINT8),
        ("observed", 3, UINT8),
        ("max_height_cm", 4, INT16),
        ("elevation_cm", 6, INT16),
    ]
    .iter()
    .map(|(name, offset, ty)| json!({"name": name, "offset": offset, "type": ty}))
    .collect();
    // Cell (0, 0) is the south-west corner, rows go north: the grid origin is that corner.
    let half = [
        g.width as f64 * g.resolution_m / 2.0,
        g.height as f64 * g.resolution_m / 2.0,
    ];
    open_object(
        out,
        &json!({
            "timestamp": time(h.stamp_ns),
            "frame_id": "world",
            "pose": {
                "position": {"x": g.center[0] - half[0], "y": g.center[1] - half[1], "z": 0.0},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            },
            "column_count": g.width,
            "cell_size": {"x": g.resolution_m, "y": g.resolution_m},
            "row_stride": g.width as usize * size,
            "cell_stride": size,
            "fields": fields,
        }),
    );
    finish_with_data(out, messages::recording::bytes_of(cells));
    true
}

impl View<[MapCell]> for LocalMapHeader {
    fn schemas() -> &'static [Schema] {
        &[Schema::Grid]
    }
    fn render(&self, p: &[MapCell], _: Schema, _: &mut ViewState, out: &mut Vec<u8>) -> bool {
        grid(&self.hdr, &self.grid, p, out)
    }
}

impl View<[MapCell]> for WorldMapHeader {
    fn schemas() -> &'static [Schema] {
        &[Schema::Grid]
    }
    fn render(&self, p: &[MapCell], _: Schema, _: &mut ViewState, out: &mut Vec<u8>) -> bool {
        grid(&self.hdr, &self.grid, p, out)
    }
}

fn color(rgb: [f64; 3]) -> Value {
    json!({"r": rgb[0], "g": rgb[1], "b": rgb[2], "a": 0.8})
}

fn cube_entity(
    stamp_ns: u64,
    id: String,
    pose: Value,
    size: [f64; 3],
    rgb: [f64; 3],
    label: &str,
) -> Value {
    let mut text_pose = pose.clone();
    text_pose["position"]["z"] = json!(size[2] + 1.0);
    json!({
        "timestamp": time(stamp_ns),
        "frame_id": "world",
        "id": id,
        "lifetime": time(0),
        "frame_locked": false,
        "cubes": [{"pose": pose, "size": {"x": size[0], "y": size[1], "z": size[2]}, "color": color(rgb)}],
        "texts": [{"pose": text_pose, "billboard": true, "font_size": 12.0, "color": color([1.0, 1.0, 1.0]), "text": label}],
    })
}

impl View<ContactList> for () {
    fn schemas() -> &'static [Schema] {
        &[Schema::SceneUpdate]
    }
    fn render(&self, p: &ContactList, _: Schema, _: &mut ViewState, out: &mut Vec<u8>) -> bool {
        let entities: Vec<Value> = p
            .as_slice()
            .iter()
            .map(|c| {
                let rgb = match c.class {
                    contact_class::BOAT => [1.0, 0.3, 0.2],
                    contact_class::CHANNEL_MARKER => [0.2, 0.8, 0.2],
                    contact_class::EXTENDED => [0.6, 0.5, 0.3],
                    _ => [0.7, 0.7, 0.7],
                };
                let yaw = c.velocity[1].atan2(c.velocity[0]);
                let pose = json!({
                    "position": {"x": c.position[0], "y": c.position[1], "z": c.extent[2] as f64 / 2.0},
                    "orientation": quaternion(0.0, 0.0, yaw),
                });
                let size = [c.extent[0] as f64, c.extent[1] as f64, c.extent[2] as f64].map(|v| v.max(0.2));
                let label = format!("#{} {}", c.id, contact_class::name(c.class));
                cube_entity(p.hdr.stamp_ns, format!("contact-{}", c.id), pose, size, rgb, &label)
            })
            .collect();
        write_json(
            out,
            &json!({"deletions": [{"timestamp": time(p.hdr.stamp_ns), "type": 1}], "entities": entities}),
        )
    }
}

impl View<GroundTruth> for () {
    fn schemas() -> &'static [Schema] {
        &[Schema::SceneUpdate]
    }
    fn render(&self, p: &GroundTruth, _: Schema, _: &mut ViewState, out: &mut Vec<u8>) -> bool {
        let entities: Vec<Value> = std::iter::once(&p.own)
            .chain(p.objects())
            .map(|o| {
                let size = o.extent.map(|v| (v as f64).max(0.2));
                let mut pose = pose(&o.pose);
                pose["position"]["z"] = json!(o.pose.position[2] + size[2] / 2.0);
                let name = truth_class::name(o.class);
                cube_entity(
                    p.hdr.stamp_ns,
                    format!("truth-{}", o.id),
                    pose,
                    size,
                    [0.3, 0.5, 1.0],
                    name,
                )
            })
            .collect();
        write_json(
            out,
            &json!({"deletions": [{"timestamp": time(p.hdr.stamp_ns), "type": 1}], "entities": entities}),
        )
    }
}

/// Mean earth radius (m): the local ENU frame is small enough for a flat-earth conversion.
const EARTH_RADIUS_M: f64 = 6_371_000.0;

impl View<InsState> for () {
    fn schemas() -> &'static [Schema] {
        &[Schema::LocationFix, Schema::FrameTransform]
    }
    fn render(&self, p: &InsState, schema: Schema, _: &mut ViewState, out: &mut Vec<u8>) -> bool {
        let [e, n, u] = p.pose.position;
        let value = if schema == Schema::LocationFix {
            let lat0 = p.origin.latitude_deg.to_radians();
            let var = p.position_sigma * p.position_sigma;
            json!({
                "timestamp": time(p.hdr.stamp_ns),
                "frame_id": "base_link",
                "latitude": p.origin.latitude_deg + (n / EARTH_RADIUS_M).to_degrees(),
                "longitude": p.origin.longitude_deg + (e / (EARTH_RADIUS_M * lat0.cos())).to_degrees(),
                "altitude": p.origin.altitude_m + u,
                "position_covariance": [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var],
                "position_covariance_type": 2,
            })
        } else {
            json!({
                "timestamp": time(p.hdr.stamp_ns),
                "parent_frame_id": "world",
                "child_frame_id": "base_link",
                "translation": {"x": e, "y": n, "z": u},
                "rotation": quaternion(p.pose.roll, p.pose.pitch, p.pose.yaw),
            })
        };
        value.is_object() && write_json(out, &value)
    }
}

impl View<Heartbeat> for () {
    fn schemas() -> &'static [Schema] {
        &[Schema::Log]
    }
    /// A log line whenever a service reports a new error, rejected input or missed deadline.
    fn render(&self, p: &Heartbeat, _: Schema, state: &mut ViewState, out: &mut Vec<u8>) -> bool {
        let problems = p.errors + p.rejected + p.missed_deadlines;
        let source = p.hdr.source.as_str();
        let before = state
            .problems
            .insert(source.to_string(), problems)
            .unwrap_or(0);
        if problems <= before {
            return false;
        }
        // Foxglove levels: 3 warning, 4 error.
        let level = if p.errors > 0 { 4 } else { 3 };
        write_json(
            out,
            &json!({
                "timestamp": time(p.hdr.stamp_ns),
                "level": level,
                "message": format!("{} ({}; errors={} rejected={} missed deadlines={})",
                    p.last_error, service_state::name(p.state), p.errors, p.rejected, p.missed_deadlines),
                "name": source,
                "file": "",
                "line": 0,
            }),
        )
    }
}

/// Topics without a Foxglove view: the raw channel only.
macro_rules! no_view {
    ($($h:ty => $p:ty),*) => { $(impl View<$p> for $h {})* };
}
no_view!(DisparityHeader => [f32], TruthImageHeader => [f32], WaterMaskHeader => [u8],
    () => ActuatorCommand, () => SequencerStatus);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_are_valid_json() {
        for s in [
            Schema::RawImage,
            Schema::Grid,
            Schema::SceneUpdate,
            Schema::LocationFix,
            Schema::FrameTransform,
            Schema::Log,
        ] {
            let v: Value =
                serde_json::from_str(&s.json_schema()).unwrap_or_else(|e| panic!("{s:?}: {e}"));
            assert_eq!(v["title"], s.name());
        }
    }

    #[test]
    fn image_message_is_json_with_base64_data() {
        let h = StereoFrameHeader {
            width: 2,
            height: 1,
            stride: 2,
            encoding: PixelEncoding::Mono8 as u32,
            ..Default::default()
        };
        let mut out = Vec::new();
        assert!(h.render(
            &[1, 2, 3, 4],
            Schema::RawImage,
            &mut ViewState::default(),
            &mut out
        ));
        let v: Value = serde_json::from_slice(&out).unwrap();
        assert_eq!(v["data"], "AQI=");
        assert_eq!(v["encoding"], "mono8");
        assert!(!h.render(
            &[1, 2, 3],
            Schema::RawImage,
            &mut ViewState::default(),
            &mut out
        ));
    }
}
