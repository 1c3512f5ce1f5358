//! One descriptor per topic: its service name, payload type, user header type and QoS. Creators and
//! openers use the same descriptor, so they cannot disagree on type or QoS.

use crate::*;
use std::marker::PhantomData;

/// Quality of service of a publish-subscribe topic. See DESIGN rules: size it consciously, the
/// shared memory per publisher is about `max_subscribers * (buffer + borrowed) + history` samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    pub max_publishers: usize,
    /// Pipeline consumers + recorder + bridge + two slots for inspection tools (`usv hz`, `usv echo`).
    pub max_subscribers: usize,
    pub history: usize,
    pub subscriber_buffer: usize,
    pub subscriber_borrowed: usize,
    /// `true`: newest wins when a subscriber's buffer is full (sensor and map data).
    /// `false`: lossless; the publisher retries for a bounded time and then reports the loss.
    pub safe_overflow: bool,
    /// Slice length (elements) the publisher reserves at start; memory grows on demand beyond it.
    pub initial_slice_len: usize,
}

impl Qos {
    /// Sensor and map data: only the newest sample matters.
    pub const fn latest(max_publishers: usize) -> Self {
        Self {
            max_publishers,
            max_subscribers: 8,
            history: 1,
            subscriber_buffer: 2,
            subscriber_borrowed: 2,
            safe_overflow: true,
            initial_slice_len: 1,
        }
    }

    /// Commands: every sample must arrive.
    pub const fn lossless(max_publishers: usize) -> Self {
        Self {
            max_publishers,
            max_subscribers: 8,
            history: 1,
            subscriber_buffer: 16,
            subscriber_borrowed: 2,
            safe_overflow: false,
            initial_slice_len: 1,
        }
    }

    const fn with_buffer(mut self, buffer: usize) -> Self {
        self.subscriber_buffer = buffer;
        self
    }

    const fn with_slice(mut self, len: usize) -> Self {
        self.initial_slice_len = len;
        self
    }
}

/// A topic: the iceoryx2 service `name` (pub-sub plus the paired event service of the same name)
/// carrying payload `P` with user header `H`.
pub struct Topic<P: ?Sized, H = ()> {
    pub name: &'static str,
    pub qos: Qos,
    types: PhantomData<fn(&P, &H)>,
}

impl<P: ?Sized, H> Topic<P, H> {
    pub const fn new(name: &'static str, qos: Qos) -> Self {
        Self {
            name,
            qos,
            types: PhantomData,
        }
    }
}

/// Name and payload description of a topic, for listings.
#[derive(Debug, Clone, Copy)]
pub struct TopicInfo {
    pub name: &'static str,
    pub payload: &'static str,
}

/// Camera pairs from the simulator or the sensors service; several heads publish on one topic and are
/// told apart by `StereoFrameHeader::head`.
pub const STEREO_FRAME: Topic<[u8], StereoFrameHeader> = Topic::new(
    "usv/sensors/stereo_frame",
    Qos::latest(4).with_slice(2 * 1280 * 960),
);
pub const INS: Topic<InsState> = Topic::new("usv/sensors/ins", Qos::latest(2).with_buffer(32));
pub const GROUND_TRUTH: Topic<GroundTruth> = Topic::new("usv/sim/ground_truth", Qos::latest(1));
pub const TRUTH_IMAGE: Topic<[f32], TruthImageHeader> = Topic::new(
    "usv/sim/truth_image",
    Qos::latest(4).with_slice(2 * 640 * 480),
);
pub const DISPARITY: Topic<[f32], DisparityHeader> = Topic::new(
    "usv/stereo/disparity",
    Qos::latest(4).with_slice(1280 * 960),
);
pub const LOCAL_MAP: Topic<[MapCell], LocalMapHeader> = Topic::new(
    "usv/perception/local_map",
    Qos::latest(4).with_slice(200 * 200),
);
pub const WATER_MASK: Topic<[u8], WaterMaskHeader> = Topic::new(
    "usv/perception/water_mask",
    Qos::latest(4).with_slice(640 * 480),
);
pub const WORLD_MAP: Topic<[MapCell], WorldMapHeader> =
    Topic::new("usv/mapper/world_map", Qos::latest(1).with_slice(200 * 200));
pub const CONTACTS: Topic<ContactList> = Topic::new("usv/tracker/contacts", Qos::latest(1));
pub const ACTUATOR_COMMAND: Topic<ActuatorCommand> =
    Topic::new("usv/control/actuator_command", Qos::lossless(1));
/// One status per sequencer cycle (up to the INS rate): a deep buffer, so the recorder keeps every
/// one of them between its wake-ups while a slow reader still never blocks the sequencer.
pub const SEQUENCER_STATUS: Topic<SequencerStatus> = Topic::new(
    "usv/control/sequencer_status",
    Qos::latest(1).with_buffer(64),
);
/// Every service publishes here; a full buffer must never block a service, so newest wins.
pub const HEARTBEAT: Topic<Heartbeat> = Topic::new(
    "usv/health/heartbeat",
    Qos {
        max_publishers: 64,
        ..Qos::latest(64).with_buffer(256)
    },
);

/// Request-response service of the sequencer: [`MissionCommand`] in, [`MissionReply`] out.
pub const MISSION_SERVICE: &str = "usv/control/mission";

/// Every publish-subscribe topic of the process graph, in pipeline order.
pub const ALL: &[TopicInfo] = &[
    info(&STEREO_FRAME, "StereoFrame"),
    info(&INS, "InsState"),
    info(&GROUND_TRUTH, "GroundTruth"),
    info(&TRUTH_IMAGE, "TruthImage"),
    info(&DISPARITY, "Disparity"),
    info(&LOCAL_MAP, "LocalMap"),
    info(&WATER_MASK, "WaterMask"),
    info(&WORLD_MAP, "WorldMap"),
    info(&CONTACTS, "ContactList"),
    info(&ACTUATOR_COMMAND, "ActuatorCommand"),
    info(&SEQUENCER_STATUS, "SequencerStatus"),
    info(&HEARTBEAT, "Heartbeat"),
];

const fn info<P: ?Sized, H>(topic: &Topic<P, H>, payload: &'static str) -> TopicInfo {
    TopicInfo {
        name: topic.name,
        payload,
    }
}

/// Runs `$body` with `$t` bound to the descriptor of the topic named `$name` (a `&str`), and returns
/// `Some(result)`, or `None` for an unknown name. The body is instantiated once per topic, so it can
/// call generic code that needs the concrete payload and header types.
#[macro_export]
macro_rules! with_topic {
    ($name:expr, $t:ident => $body:expr) => {{
        use $crate::topics as __t;
        let __name: &str = $name;
        if __name == __t::STEREO_FRAME.name {
            let $t = &__t::STEREO_FRAME;
            Some($body)
        } else if __name == __t::INS.name {
            let $t = &__t::INS;
            Some($body)
        } else if __name == __t::GROUND_TRUTH.name {
            let $t = &__t::GROUND_TRUTH;
            Some($body)
        } else if __name == __t::TRUTH_IMAGE.name {
            let $t = &__t::TRUTH_IMAGE;
            Some($body)
        } else if __name == __t::DISPARITY.name {
            let $t = &__t::DISPARITY;
            Some($body)
        } else if __name == __t::LOCAL_MAP.name {
            let $t = &__t::LOCAL_MAP;
            Some($body)
        } else if __name == __t::WATER_MASK.name {
            let $t = &__t::WATER_MASK;
            Some($body)
        } else if __name == __t::WORLD_MAP.name {
            let $t = &__t::WORLD_MAP;
            Some($body)
        } else if __name == __t::CONTACTS.name {
            let $t = &__t::CONTACTS;
            Some($body)
        } else if __name == __t::ACTUATOR_COMMAND.name {
            let $t = &__t::ACTUATOR_COMMAND;
            Some($body)
        } else if __name == __t::SEQUENCER_STATUS.name {
            let $t = &__t::SEQUENCER_STATUS;
            Some($body)
        } else if __name == __t::HEARTBEAT.name {
            let $t = &__t::HEARTBEAT;
            Some($body)
        } else {
            None
        }
    }};
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_names_are_unique_and_dispatchable() {
        let mut names: Vec<_> = ALL.iter().map(|t| t.name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), ALL.len());
        for t in ALL {
            let found = crate::with_topic!(t.name, topic => topic.name);
            assert_eq!(found, Some(t.name));
        }
        assert!(crate::with_topic!("usv/nope", topic => topic.name).is_none());
    }
}
