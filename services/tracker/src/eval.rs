//! Scores a contact list against ground truth, for `usv eval` and tests. Pure functions.

use crate::line_of_sight;
use messages::{contact_class, truth_class, ContactList, GroundTruth, Pose};

/// How one truth object was tracked at one instant.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ObjectScore {
    pub truth_id: u32,
    /// Range from the own vessel in boat lengths of the object (the paper's Figure 11 metric).
    pub range_lengths: f64,
    /// Id of the nearest confirmed track within the gate, if any.
    pub track_id: Option<u32>,
    /// That track had no detection this frame (out of view it is a prediction).
    pub coasting: bool,
    /// The class that track was reported as ([`messages::contact_class`]; 0 without a track).
    pub class: u8,
    /// |speed error| / true speed in percent (None when the object is slower than 0.5 m/s).
    pub speed_error_pct: Option<f64>,
    /// Heading error (rad, wrapped to +-pi; None below 0.5 m/s).
    pub heading_error: Option<f64>,
    /// Position error along and across the own vessel's line of sight to the object (m), and the
    /// track's 1-sigma in those directions.
    pub along_error: f64,
    pub cross_error: f64,
    pub along_sigma: f64,
    pub cross_sigma: f64,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackScore {
    pub objects: Vec<ObjectScore>,
    /// Confirmed tracks with no truth object within the gate.
    pub false_tracks: u32,
}

impl TrackScore {
    pub fn detected(&self) -> usize {
        self.objects.iter().filter(|o| o.track_id.is_some()).count()
    }
}

/// The contact class a true object's track should be reported as: a buoy or a channel marker is
/// a marker; a pylon, a bridge or anything else not a boat an extended obstacle.
pub fn expected_contact_class(truth: u8) -> u8 {
    match truth {
        truth_class::BOAT => contact_class::BOAT,
        truth_class::BUOY | truth_class::MARKER => contact_class::CHANNEL_MARKER,
        _ => contact_class::EXTENDED,
    }
}

/// Matches each truth object (own vessel excluded) to the nearest confirmed track within `gate_m`.
pub fn score(contacts: &ContactList, truth: &GroundTruth, own: &Pose, gate_m: f64) -> TrackScore {
    let mut out = TrackScore::default();
    let confirmed = || contacts.as_slice().iter().filter(|c| c.confirmed == 1);
    for o in truth.objects() {
        let (tx, ty) = (o.pose.position[0], o.pose.position[1]);
        let (dx, dy) = (tx - own.position[0], ty - own.position[1]);
        let (sight, range) = line_of_sight::direction([dx, dy]);
        let mut s = ObjectScore {
            truth_id: o.id,
            range_lengths: range / (o.extent[0] as f64).max(0.1),
            ..Default::default()
        };
        let best = confirmed()
            .map(|c| (c, (c.position[0] - tx).hypot(c.position[1] - ty)))
            .filter(|(_, d)| *d <= gate_m)
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.id.cmp(&b.0.id)));
        if let Some((c, _)) = best {
            s.track_id = Some(c.id);
            s.coasting = c.coasting == 1;
            s.class = c.class;
            let speed = o.velocity[0].hypot(o.velocity[1]);
            if speed >= 0.5 {
                let est = c.velocity[0].hypot(c.velocity[1]);
                s.speed_error_pct = Some((est - speed).abs() / speed * 100.0);
                let e = c.velocity[1].atan2(c.velocity[0]) - o.velocity[1].atan2(o.velocity[0]);
                s.heading_error = Some(
                    (e + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                        - std::f64::consts::PI,
                );
            }
            (s.along_error, s.cross_error) =
                line_of_sight::along_across(sight, [c.position[0] - tx, c.position[1] - ty]);
            let p = |i: usize, j: usize| c.covariance[i * 4 + j] as f64;
            let (along_var, cross_var) =
                line_of_sight::along_across_variances(sight, [p(0, 0), p(0, 1), p(1, 1)]);
            s.along_sigma = along_var.max(0.0).sqrt();
            s.cross_sigma = cross_var.max(0.0).sqrt();
        }
        out.objects.push(s);
    }
    out.false_tracks = confirmed()
        .filter(|c| {
            !truth.objects().iter().any(|o| {
                (c.position[0] - o.pose.position[0]).hypot(c.position[1] - o.pose.position[1])
                    <= gate_m
            })
        })
        .count() as u32;
    out
}

/// Whether two contact lists report the same contacts (id, class, position, confirmation), in
/// the same order: a tracker run again over a recording's maps against the recorded one.
pub fn same_contacts(a: &ContactList, b: &ContactList) -> bool {
    a.count == b.count
        && a.as_slice().iter().zip(b.as_slice()).all(|(x, y)| {
            x.id == y.id
                && x.class == y.class
                && x.position == y.position
                && x.confirmed == y.confirmed
        })
}

/// Accumulates along- and cross-track errors and sigmas over a run for the paper's 3-sigma RMS
/// ratio (along / cross; 1.65 for position in the Hammerhead following run). Only frames in which
/// the track had a detection count: a prediction held out of view grows its covariance in every
/// direction and would swamp the ratio the measurements give.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AlongCross {
    pub n: u64,
    pub along_err2: f64,
    pub cross_err2: f64,
    pub along_var: f64,
    pub cross_var: f64,
}

impl AlongCross {
    pub fn add(&mut self, s: &ObjectScore) {
        if s.track_id.is_none() || s.coasting {
            return;
        }
        self.n += 1;
        self.along_err2 += s.along_error * s.along_error;
        self.cross_err2 += s.cross_error * s.cross_error;
        self.along_var += s.along_sigma * s.along_sigma;
        self.cross_var += s.cross_sigma * s.cross_sigma;
    }
    /// RMS 3-sigma along over RMS 3-sigma across (None before any sample).
    pub fn sigma_ratio(&self) -> Option<f64> {
        (self.n > 0 && self.cross_var > 0.0).then(|| (self.along_var / self.cross_var).sqrt())
    }
    /// RMS error along and across (m).
    pub fn rms_errors(&self) -> Option<(f64, f64)> {
        (self.n > 0).then(|| {
            let n = self.n as f64;
            ((self.along_err2 / n).sqrt(), (self.cross_err2 / n).sqrt())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::{Contact, TruthObject};

    #[test]
    fn scores_detection_speed_heading_and_false_tracks() {
        let mut truth = GroundTruth::default();
        truth.objects[0] = TruthObject {
            id: 7,
            pose: Pose {
                position: [30.0, 0.0, 0.0],
                ..Default::default()
            },
            velocity: [0.0, 5.0, 0.0],
            extent: [6.0, 2.0, 1.5],
            ..Default::default()
        };
        truth.objects[1] = TruthObject {
            id: 8,
            pose: Pose {
                position: [-40.0, 0.0, 0.0],
                ..Default::default()
            },
            extent: [1.0, 1.0, 2.0],
            ..Default::default()
        };
        truth.object_count = 2;
        let mut list = ContactList::default();
        let mut cov = [0f32; 16];
        cov[0] = 4.0; // 2 m east sigma: along the line of sight to the boat
        cov[5] = 0.25;
        list.contacts[0] = Contact {
            id: 3,
            class: messages::contact_class::BOAT,
            confirmed: 1,
            position: [31.0, 0.5],
            velocity: [0.0, 5.2],
            covariance: cov,
            ..Default::default()
        };
        list.contacts[1] = Contact {
            id: 4,
            confirmed: 1,
            position: [0.0, 50.0],
            ..Default::default()
        };
        list.contacts[2] = Contact {
            id: 5,
            confirmed: 0,
            position: [-40.0, 0.0],
            ..Default::default()
        };
        list.count = 3;
        let s = score(&list, &truth, &Pose::default(), 3.0);
        assert_eq!(s.objects.len(), 2);
        let boat = s.objects[0];
        assert_eq!(boat.track_id, Some(3));
        assert_eq!(boat.class, messages::contact_class::BOAT);
        assert!((boat.range_lengths - 5.0).abs() < 1e-9);
        assert!((boat.speed_error_pct.unwrap() - 4.0).abs() < 1e-6);
        assert!(boat.heading_error.unwrap().abs() < 1e-9);
        assert!((boat.along_error - 1.0).abs() < 1e-9 && (boat.cross_error - 0.5).abs() < 1e-9);
        assert!((boat.along_sigma - 2.0).abs() < 1e-6 && (boat.cross_sigma - 0.5).abs() < 1e-6);
        // The tentative track on the marker does not count.
        assert_eq!(s.objects[1].track_id, None);
        assert_eq!(s.detected(), 1);
        assert_eq!(s.false_tracks, 1);
        let mut ac = AlongCross::default();
        for o in &s.objects {
            ac.add(o);
        }
        assert!((ac.sigma_ratio().unwrap() - 4.0).abs() < 1e-6);
        // A held prediction (coasting) with a wide covariance across does not count.
        ac.add(&ObjectScore {
            coasting: true,
            cross_sigma: 50.0,
            ..boat
        });
        assert!((ac.sigma_ratio().unwrap() - 4.0).abs() < 1e-6);
        assert_eq!(ac.n, 1);
    }
}
