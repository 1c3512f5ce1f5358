#!/usr/bin/env python3
"""Side-by-side accuracy and speed of our `stereo match` (BM, SGM) and OpenCV StereoBM / StereoSGBM
(MODE_SGBM_3WAY), in one run on the same inputs.

Accuracy: Middlebury Motorcycle (testdata/), 96 disparities; density and bad-pixel rates (>1 px,
>2 px) over all ground-truth pixels (missing counts as bad) and over produced pixels; subpixel
quality: mean error over produced pixels within 1 px of the truth ("subpx") and the share of
disparities within 1/8 px of a whole pixel ("whole", 25 % if unbiased).
Speed: the same pair resized to 1280x960, 128 disparities. Each method runs --repeat times per
round and the methods take turns for --rounds rounds, so load from other jobs on a shared machine
falls on all of them alike; the table gives the median and the best time over all runs and the
speed-up of each from the same run.

Usage: scripts/compare_opencv.py [--bin PATH] [--repeat N] [--rounds N] [--only bm|sgm]
(build first: cargo build --release -p stereo)
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

try:
    import cv2
    import numpy as np
except ImportError:
    subprocess.check_call([sys.executable, "-m", "pip", "install", "-q",
                           "opencv-python-headless", "numpy"])
    import cv2
    import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "testdata")
ACC_NDISP, SPEED_NDISP, SPEED_SIZE = 96, 128, (1280, 960)


def default_bin():
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(HERE, "..", "..", "..", "target"))
    return os.path.join(target, "release", "stereo")


def metrics(disp, valid, gt):
    known = np.isfinite(gt)
    n = known.sum()
    v = valid & known
    err = np.abs(np.where(v, disp, 0) - np.where(known, gt, 0))
    missing = (known & ~valid).sum()
    return dict(
        density=v.sum() / n,
        bad1_all=(((err > 1) & v).sum() + missing) / n,
        bad2_all=(((err > 2) & v).sum() + missing) / n,
        bad1_valid=((err > 1) & v).sum() / max(v.sum(), 1),
        bad2_valid=((err > 2) & v).sum() / max(v.sum(), 1),
        # Subpixel quality: the mean error over produced pixels within 1 px of the truth, and the
        # share of disparities (16 px or more) within 1/8 px of a whole pixel, 25 % if unbiased;
        # a parabola fit to a V-shaped cost bunches them there ("pixel locking").
        subpx_mae=err[v & (err < 1)].mean(),
        near_whole=near_whole(disp[v & (disp >= 16)]),
    )


def near_whole(d):
    frac = d - np.floor(d)
    return ((frac < 0.125) | (frac >= 0.875)).sum() / max(d.size, 1)


def opencv_matchers(ndisp):
    # Same checks as ours where OpenCV has them: 9x9 window, texture 10, uniqueness 10,
    # left-right max diff 1 (BM); 5x5 blocks, uniqueness 5, LR 1 (SGBM, OpenCV's usual
    # settings; a higher uniqueness trades its density for accuracy); no speckle filter.
    bm = cv2.StereoBM_create(numDisparities=ndisp, blockSize=9)
    bm.setPreFilterCap(31)
    bm.setTextureThreshold(10)
    bm.setUniquenessRatio(10)
    bm.setDisp12MaxDiff(1)
    bs = 5

    def sgbm(uniqueness):
        return cv2.StereoSGBM_create(minDisparity=0, numDisparities=ndisp, blockSize=bs,
                                     P1=8 * bs * bs, P2=32 * bs * bs, disp12MaxDiff=1,
                                     uniquenessRatio=uniqueness,
                                     mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    # Ours uses uniqueness 20; OpenCV is shown both at its usual 5 and at 20.
    return {"opencv StereoBM": bm, "opencv SGBM-3WAY": sgbm(5), "opencv SGBM-3WAY u20": sgbm(20)}


def run_opencv(m, left, right, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        d = m.compute(left, right)
        times.append(1e3 * (time.perf_counter() - t))
    return d.astype(np.float32) / 16.0, d >= 0, times


def run_ours(binary, algo, left_path, right_path, ndisp, repeat, tmp):
    """Runs `stereo match`; its --repeat loop times the matcher alone. Returns every run's ms
    approximated by the median and best it prints (the binary does not list each run)."""
    out = os.path.join(tmp, f"ours_{algo}.png")
    res = subprocess.run([binary, "match", "--left", left_path, "--right", right_path,
                          "--ndisp", str(ndisp), "--algo", algo, "--out", out,
                          "--repeat", str(repeat)], check=True, capture_output=True, text=True)
    m = re.search(r"median matching time ([0-9.]+) ms(?: \(best ([0-9.]+) ms\))?", res.stdout)
    d = cv2.imread(out, cv2.IMREAD_UNCHANGED).astype(np.float32)
    # Binaries before the best time was printed: the median stands in for it.
    return d / 256.0, d > 0, (float(m.group(1)), float(m.group(2) or m.group(1)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=default_bin())
    ap.add_argument("--repeat", type=int, default=10, help="runs per method and round")
    ap.add_argument("--rounds", type=int, default=3, help="turns each method takes")
    ap.add_argument("--only", choices=("bm", "sgm"), help="compare one matcher family only")
    a = ap.parse_args()
    lp, rp = os.path.join(DATA, "motorcycle_left.png"), os.path.join(DATA, "motorcycle_right.png")
    gt = np.load(os.path.join(DATA, "motorcycle_disp.npz"))["arr_0"]
    left, right = cv2.imread(lp, cv2.IMREAD_GRAYSCALE), cv2.imread(rp, cv2.IMREAD_GRAYSCALE)
    print(f"OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads; our binary {a.bin}")
    with tempfile.TemporaryDirectory() as tmp:
        big_l, big_r = os.path.join(tmp, "l.png"), os.path.join(tmp, "r.png")
        bl = cv2.resize(left, SPEED_SIZE, interpolation=cv2.INTER_CUBIC)
        br = cv2.resize(right, SPEED_SIZE, interpolation=cv2.INTER_CUBIC)
        cv2.imwrite(big_l, bl)
        cv2.imwrite(big_r, br)
        acc_cv, speed_cv = opencv_matchers(ACC_NDISP), opencv_matchers(SPEED_NDISP)
        fams = {"bm": ["opencv StereoBM"],
                "sgm": ["opencv SGBM-3WAY", "opencv SGBM-3WAY u20"]}
        algos = [a.only] if a.only else ["bm", "sgm"]
        names = [n for al in algos for n in fams[al]] + [f"ours {al}" for al in algos]
        acc = {}
        for name in names:
            if name.startswith("ours"):
                d, v, _ = run_ours(a.bin, name[5:], lp, rp, ACC_NDISP, 1, tmp)
            else:
                d, v, _ = run_opencv(acc_cv[name], left, right, 1)
            acc[name] = metrics(d, v, gt)
        # Per method: medians of each round (ours prints its own) and the best single run.
        med, best = {n: [] for n in names}, {n: [] for n in names}
        for _ in range(a.rounds):
            for name in names:
                if name.startswith("ours"):
                    _, _, (m, b) = run_ours(a.bin, name[5:], big_l, big_r, SPEED_NDISP,
                                            a.repeat, tmp)
                else:
                    _, _, ts = run_opencv(speed_cv[name], bl, br, a.repeat)
                    m, b = float(np.median(ts)), min(ts)
                med[name].append(m)
                best[name].append(b)
    ms = {n: (float(np.median(med[n])), min(best[n])) for n in names}
    ref = {"ours bm": "opencv StereoBM", "ours sgm": "opencv SGBM-3WAY"}
    print(f"\nAccuracy: Motorcycle 741x500, {ACC_NDISP} disparities. "
          f"Speed: {SPEED_SIZE[0]}x{SPEED_SIZE[1]}, {SPEED_NDISP} disparities, "
          f"{a.rounds} rounds of {a.repeat} runs per method, taking turns.")
    print(f"{'method':22} {'density':>8} {'bad1 all':>9} {'bad1 val':>9} {'bad2 all':>9} "
          f"{'bad2 val':>9} {'subpx':>6} {'whole':>6} {'ms med':>8} {'ms best':>8} "
          f"{'speedup med':>12} {'best':>7}")
    for name in names:
        m, (t_med, t_best) = acc[name], ms[name]
        speed = ""
        if name in ref:
            r_med, r_best = ms[ref[name]]
            speed = f"{r_med / t_med:11.2f}x {r_best / t_best:6.2f}x"
        print(f"{name:22} {100*m['density']:7.1f}% {100*m['bad1_all']:8.1f}% "
              f"{100*m['bad1_valid']:8.1f}% {100*m['bad2_all']:8.1f}% {100*m['bad2_valid']:8.1f}% "
              f"{m['subpx_mae']:6.3f} {100*m['near_whole']:5.1f}% "
              f"{t_med:8.1f} {t_best:8.1f} {speed}")


if __name__ == "__main__":
    main()
