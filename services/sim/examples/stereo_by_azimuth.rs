//! Stereo error of a head by depth and azimuth, through the stereo service's own pipeline, for the
//! Hammerhead layout (toed cameras, oversized rectified view) and the former ideal layout (each
//! pair yawed as a whole). Shows where the toed geometry costs precision: the sides of the rectified
//! view, which are stretched (paper 001, section 4).
//!
//! `cargo run --release -p sim --example stereo_by_azimuth -- [scenario.toml ...]`

use sim::{Command, Simulator};
use std::time::Instant;
use stereo::calib::Calibration;
use stereo::disparity::MatcherConfig;
use stereo::pipeline::{FramePipeline, PlaneSearch};

fn main() -> anyhow::Result<()> {
    let mut paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/");
        paths = ["bridge_pylons.toml", "channel_markers.toml"]
            .map(|f| format!("{dir}{f}"))
            .into();
    }
    for path in &paths {
        for toed in [true, false] {
            let mut world = sim::scenario::load_world(std::path::Path::new(path))?;
            let h = &mut world.heads[0];
            if !toed {
                h.mount.rpy[2] = h.toe;
                h.mount.position.y = 0.0;
                h.toe = 0.0;
                h.oversize = 1.0;
            }
            let mut sim = Simulator::new(world);
            let throttle = sim.state().throttle;
            sim.step(
                Command {
                    rudder: 0.0,
                    throttle,
                },
                1.0,
            );
            let head = sim.world.heads[0].clone();
            let calib = Calibration::from_toml(&head.calibration().to_toml())?;
            let view = head.rectified()?;
            let (w, h) = (view.width, view.height);
            let (rw, rh) = (head.width as usize, head.height as usize);
            let n = head.image_len();
            let (mut left, mut right) = (vec![0u8; n], vec![0u8; n]);
            sim.render_head(0, &mut left, &mut right)?;
            let (mut truth, mut labels) = (vec![0f32; w * h], vec![0u8; w * h]);
            sim.render_truth_view(0, &view, &mut truth, &mut labels)?;
            let matcher: MatcherConfig = toml::from_str("algo = \"bm\"")?;
            let mut pipeline = FramePipeline::new(&calib, &matcher, PlaneSearch::default())?;
            let mut times = Vec::new();
            for _ in 0..5 {
                let t0 = Instant::now();
                pipeline.process(rw, rh, &left, &right)?;
                times.push(t0.elapsed().as_secs_f64() * 1e3);
            }
            times.sort_by(f64::total_cmp);
            let disparity = pipeline.process(rw, rh, &left, &right)?.disparity;
            let fb = view.f * view.baseline;
            // Azimuth relative to the bar's forward axis (the rectified axis of a toed head, the
            // head's yaw for the former layout).
            let yaw0 = if toed { 0.0 } else { head.mount.rpy[2] };
            println!(
                "{} {}: rectified {w}x{h}, f {:.1} px, stereo {:.1} ms median of 5",
                sim.world.name,
                if toed {
                    "toed (Hammerhead)"
                } else {
                    "ideal, pair yawed"
                },
                view.f,
                times[2]
            );
            println!(
                "  {:>9} {:>11} {:>8} {:>8} {:>13} {:>10} {:>14}",
                "depth m",
                "azimuth",
                "pixels",
                "density",
                "median |dd| px",
                "|dZ| m",
                "sigma 0.25px m"
            );
            for (zlo, zhi) in [(15.0, 40.0), (40.0, 80.0), (80.0, 130.0), (130.0, 260.0)] {
                for (alo, ahi) in [
                    (-60.0, -30.0),
                    (-30.0, -10.0),
                    (-10.0, 10.0),
                    (10.0, 30.0),
                    (30.0, 60.0),
                ] {
                    let (mut errs, mut seen, mut zsum) = (Vec::new(), 0usize, 0.0);
                    for i in 0..w * h {
                        // Solid surfaces only (not sky, not water).
                        if labels[i] <= 1 || truth[i] <= 0.0 {
                            continue;
                        }
                        let z = fb / truth[i] as f64;
                        let az = (yaw0 - ((i % w) as f64 - view.cx).atan2(view.f)).to_degrees();
                        if z < zlo || z >= zhi || az < alo || az >= ahi {
                            continue;
                        }
                        seen += 1;
                        if let Some(d) = disparity.get(i % w, i / w) {
                            errs.push((d as f64 - truth[i] as f64).abs());
                            zsum += z;
                        }
                    }
                    if seen < 200 || errs.is_empty() {
                        continue;
                    }
                    errs.sort_by(f64::total_cmp);
                    let med = errs[errs.len() / 2];
                    let z = zsum / errs.len() as f64;
                    println!(
                        "  {:>9} {:>11} {seen:>8} {:>8.2} {med:>13.3} {:>10.2} {:>14.2}",
                        format!("{zlo}-{zhi}"),
                        format!("{alo}..{ahi}"),
                        errs.len() as f64 / seen as f64,
                        z * z * med / fb,
                        z * z * 0.25 / fb
                    );
                }
            }
        }
    }
    Ok(())
}
