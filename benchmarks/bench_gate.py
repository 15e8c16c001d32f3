"""Gate cost per frame (full res vs downscaled) and GelSight Mini IoU; numbers in docs/runtime.md."""
import time, cv2, numpy as np
from tactile_force.edge import ContactGate, GateOptions
import os
D = os.environ.get("TACTILE_FORCE_SHARED_DATA", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data")) + "/"
bg = cv2.imread(D + "digit_backgrounds/aurova_background_b.png")
img = cv2.imread(D + "aurova_digit_grasp/images/1510.png")
z = np.load(D + "gelsight_mini_ball_presses.npz")
yy, xx = np.mgrid[:480, :640]
for ds in (1, 2, 4):
    g = ContactGate(GateOptions(downscale=ds)); g.capture_background([bg])
    for _ in range(50): g.update(img)
    t = []
    for _ in range(500):
        t0 = time.perf_counter_ns(); g.update(img); t.append((time.perf_counter_ns() - t0) / 1e6)
    ious = []
    tg = []
    for im, (cx, cy), r in zip(z["imgs"], z["touch_center"].astype(float), z["touch_radius"].astype(float)):
        gg = ContactGate(GateOptions(threshold=25.0, downscale=ds)); gg.capture_background([z["f0"]])
        t0 = time.perf_counter_ns(); m = gg.update(im).mask > 0; tg.append((time.perf_counter_ns() - t0) / 1e6)
        lab = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
        ious.append((m & lab).sum() / (m | lab).sum())
    print(f"downscale {ds}: DIGIT 320x240 gate p50 {np.percentile(t,50):.3f} ms p99 {np.percentile(t,99):.3f} ms | "
          f"GelSight 480x640 IoU mean {np.mean(ious):.3f} min {np.min(ious):.3f}, first-call {np.median(tg):.2f} ms")
