//! Connected regions of the joined cue mask and the rule base that accepts them as water (section 2).

use crate::config::RuleParams;
use messages::water_cue;

/// Connected-component labelling (8-connectivity) of the non-zero pixels of `mask` by union-find.
/// Labels are 1-based in first-pixel scan order (0 = background), so they are deterministic. Returns
/// the number of regions.
pub fn label(
    mask: &[u8],
    width: usize,
    height: usize,
    labels: &mut [u32],
    parent: &mut Vec<u32>,
) -> usize {
    parent.clear();
    parent.push(0);
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            let next = parent[parent[a as usize] as usize];
            parent[a as usize] = next;
            a = next;
        }
        a
    }
    fn union(parent: &mut [u32], a: u32, b: u32) -> u32 {
        let (ra, rb) = (find(parent, a), find(parent, b));
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        parent[hi as usize] = lo;
        lo
    }
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            if mask[i] == 0 {
                labels[i] = 0;
                continue;
            }
            let mut l = 0u32;
            let mut join = |n: u32, parent: &mut Vec<u32>| {
                if n != 0 {
                    l = if l == 0 { n } else { union(parent, l, n) };
                }
            };
            if x > 0 {
                join(labels[i - 1], parent);
            }
            if y > 0 {
                let up = i - width;
                if x > 0 {
                    join(labels[up - 1], parent);
                }
                join(labels[up], parent);
                if x + 1 < width {
                    join(labels[up + 1], parent);
                }
            }
            if l == 0 {
                l = parent.len() as u32;
                parent.push(l);
            }
            labels[i] = l;
        }
    }
    // Compact: roots get consecutive ids in order of first appearance (roots are the smallest label
    // of their set, so ascending label order is scan order).
    for a in 1..parent.len() {
        let r = find(parent, a as u32);
        parent[a] = r;
    }
    let mut next = 0u32;
    for a in 1..parent.len() {
        if parent[a] == a as u32 {
            next += 1;
            parent[a] = next | 0x8000_0000;
        } else {
            parent[a] = parent[parent[a] as usize];
        }
    }
    for l in labels.iter_mut() {
        if *l != 0 {
            *l = parent[*l as usize] & 0x7fff_ffff;
        }
    }
    next as usize
}

/// What the rule base looks at, accumulated over a region's pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RegionStats {
    pub pixels: u32,
    /// Pixels with each joined cue: colour, texture, reflection, zero disparity.
    pub cues: [u32; 4],
    pub above_horizon: u32,
    /// Pixels where the zero-disparity cue can fire at all (outside the matcher's blind margin).
    pub zero_disparity_known: u32,
    /// Perimeter samples with a stereo point that is not a reflection, and those above the ground.
    pub range_points: u32,
    pub above_ground: u32,
    /// Inclusive bounding box: u0, v0, u1, v1.
    pub bbox: [u32; 4],
    pub sum_u: u64,
    pub sum_v: u64,
}

impl RegionStats {
    pub fn add(
        &mut self,
        u: usize,
        v: usize,
        cues: u8,
        above_horizon: bool,
        zero_disparity_known: bool,
    ) {
        if self.pixels == 0 {
            self.bbox = [u as u32, v as u32, u as u32, v as u32];
        } else {
            self.bbox[0] = self.bbox[0].min(u as u32);
            self.bbox[1] = self.bbox[1].min(v as u32);
            self.bbox[2] = self.bbox[2].max(u as u32);
            self.bbox[3] = self.bbox[3].max(v as u32);
        }
        self.pixels += 1;
        for (k, bit) in CUE_BITS.iter().enumerate() {
            self.cues[k] += (cues & bit != 0) as u32;
        }
        self.above_horizon += above_horizon as u32;
        self.zero_disparity_known += zero_disparity_known as u32;
        self.sum_u += u as u64;
        self.sum_v += v as u64;
    }
}

pub const CUE_BITS: [u8; 4] = [
    water_cue::COLOR,
    water_cue::TEXTURE,
    water_cue::REFLECTION,
    water_cue::ZERO_DISPARITY,
];

/// Why a region was rejected (or accepted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    Water,
    TooSmall,
    AboveHorizon,
    AboveGround,
    /// Too few cues present, or none of the water-specific ones (colour, reflection) strong enough.
    InvalidCues,
}

/// The rule base of section 2.
pub fn judge(s: &RegionStats, p: &RuleParams) -> Verdict {
    if (s.pixels as usize) < p.min_pixels {
        return Verdict::TooSmall;
    }
    let n = s.pixels as f32;
    if s.above_horizon as f32 > p.max_above_horizon * n {
        return Verdict::AboveHorizon;
    }
    if s.range_points > 0 && s.above_ground as f32 > p.max_above_ground * s.range_points as f32 {
        return Verdict::AboveGround;
    }
    // Valid combinations: colour (sky reflection) with at least one more cue, or stereo reflections
    // with zero disparity next to them (reflections of far things); texture alone never decides.
    let share = s.cues.map(|c| c as f32 / n);
    let present = share.iter().filter(|&&f| f >= p.min_cue_share).count();
    let color_led = share[0] >= p.min_color_share && present >= p.min_cues;
    // Where the matcher cannot produce disparities (its blind left margin) zero disparity carries
    // no evidence, so it is asked for only when most of the region could show it.
    let known = s.zero_disparity_known as f32;
    let zero_disparity = known < 0.5 * n || s.cues[3] as f32 >= p.min_cue_share * known;
    let reflection_led = share[2] >= p.min_reflection_share && zero_disparity;
    if !(color_led || reflection_led) {
        return Verdict::InvalidCues;
    }
    Verdict::Water
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_u_shape_as_one_region_and_separates_diagonal_free_blobs() {
        #[rustfmt::skip]
        let m: Vec<u8> = vec![
            1, 0, 1, 0, 0, 1,
            1, 0, 1, 0, 0, 0,
            1, 1, 1, 0, 1, 0,
            0, 0, 0, 0, 0, 1,
        ];
        let mut labels = vec![0; m.len()];
        let mut parent = Vec::new();
        let n = label(&m, 6, 4, &mut labels, &mut parent);
        assert_eq!(n, 3);
        assert_eq!(labels[0], 1);
        assert_eq!(labels[2], 1, "U joined through the bottom");
        assert_eq!(labels[5], 2);
        assert_eq!(labels[2 * 6 + 4], 3);
        assert_eq!(labels[3 * 6 + 5], 3, "8-connected diagonal");
    }

    fn stats(pixels: u32, cues: [u32; 4]) -> RegionStats {
        RegionStats {
            pixels,
            cues,
            zero_disparity_known: pixels,
            ..RegionStats::default()
        }
    }

    #[test]
    fn rules_reject_small_single_cue_and_non_specific_regions() {
        let p = RuleParams::default();
        assert_eq!(judge(&stats(500, [400, 450, 0, 300]), &p), Verdict::Water);
        assert_eq!(judge(&stats(500, [0, 100, 200, 300]), &p), Verdict::Water);
        assert_eq!(judge(&stats(20, [20, 20, 0, 20]), &p), Verdict::TooSmall);
        assert_eq!(judge(&stats(500, [500, 0, 0, 0]), &p), Verdict::InvalidCues);
        assert_eq!(
            judge(&stats(500, [0, 500, 0, 500]), &p),
            Verdict::InvalidCues
        );
        let mut sky = stats(500, [500, 500, 0, 0]);
        sky.above_horizon = 400;
        assert_eq!(judge(&sky, &p), Verdict::AboveHorizon);
        let mut wall = stats(500, [500, 500, 0, 0]);
        wall.range_points = 300;
        wall.above_ground = 200;
        assert_eq!(judge(&wall, &p), Verdict::AboveGround);
    }
}
