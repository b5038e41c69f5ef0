// The front camera's lens: where a direction seen from the blimp lands in the fisheye image, and where a touch
// on the skin is as a direction. The dome and the touch markers both go through here, so a marker drawn into the
// fisheye image sits on the dome exactly where that image shows the spot.
//
// Camera coordinates are OpenCV's: x right, y down, z along the optical axis (forward).

// From a daemon without GET /lens (older than the route) the lens is taken as the simulator's: an equidistant
// 180 degree fisheye whose image circle is inscribed in the frame (feelium/cameras/sim_front.py). As an OpenCV
// fisheye model that is K with f = radius / (pi / 2) and D = 0 (theta_d = theta): what /lens serves as "nominal".
const FALLBACK_FOV_DEG = 180;

// Where the sensitive patch of skin is, seen from the front camera: the blimp's face, centred on the front
// camera's optical axis; u runs to the wearer's right and v downwards (the rear camera looks outwards from
// inside, as the wearer does), and the patch spans these angles of azimuth and elevation around the camera.
// GET /lens serves them as "skin_patch_deg" (an assumed geometry, feelium/skin/face.py); these are for a daemon
// older than that field.
export const SKIN_PATCH_DEG = [100, 75];

const rad = (deg) => (deg * Math.PI) / 180;

export class Lens {
  // model: the GET /lens answer, {model: "opencv_fisheye", width, height, K: 3x3 without skew, D: [k1..k4],
  // source: "sim" | "calibrated" | "nominal"}; "fallback" is this page's own stand-in.
  constructor(model) {
    this.source = model.source;
    this.width = model.width; this.height = model.height;
    const K = model.K;
    this.fx = K[0][0]; this.fy = K[1][1]; this.cx = K[0][2]; this.cy = K[1][2];
    this.D = model.D;
    this.skinPatchDeg = model.skin_patch_deg || SKIN_PATCH_DEG;
    // The widest angle off the axis the image still shows: how far the dome has to reach.
    this.maxTheta = Math.min(Math.PI, this.thetaAtRadius(Math.hypot(this.width, this.height) / 2 / Math.max(this.fx, this.fy)));
  }

  static equidistant(width, height, fovDeg = FALLBACK_FOV_DEG) {
    const f = Math.min(width, height) / 2 / rad(fovDeg / 2);
    // (size - 1) / 2: pixel centres are on integers, as in the simulator and OpenCV
    const K = [[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]];
    return new Lens({ model: "opencv_fisheye", width, height, K, D: [0, 0, 0, 0], source: "fallback" });
  }

  distort(theta) {
    const t2 = theta * theta, [k1, k2, k3, k4] = this.D;
    return theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
  }

  // The inverse of distort() by Newton's method (it is monotonic over a lens's useful range).
  thetaAtRadius(thetaD) {
    let theta = thetaD;
    for (let i = 0; i < 20; i++) {
      const h = 1e-6, f = this.distort(theta) - thetaD, df = (this.distort(theta + h) - this.distort(theta - h)) / (2 * h);
      if (!(Math.abs(df) > 1e-9)) break;
      const next = theta - f / df;
      if (Math.abs(next - theta) < 1e-9) return next;
      theta = next;
    }
    return theta;
  }

  // Pixel [px, py] of direction [x, y, z], as cv2.fisheye.projectPoints computes it. The angle off the axis is
  // taken with atan2, so directions at and beyond 90 degrees (a 180+ degree lens sees them) project too.
  project([x, y, z]) {
    const rho = Math.hypot(x, y);
    if (rho < 1e-12) return [this.cx, this.cy];
    const thetaD = this.distort(Math.atan2(rho, z));
    const xd = (thetaD * x) / rho, yd = (thetaD * y) / rho;
    return [this.fx * xd + this.cx, this.fy * yd + this.cy];
  }

  // The direction (unit vector, camera coordinates) of skin position u, v under the patch assumption above.
  skinDirection(u, v) {
    const az = rad((u - 0.5) * this.skinPatchDeg[0]), el = rad((0.5 - v) * this.skinPatchDeg[1]);
    return [Math.sin(az) * Math.cos(el), -Math.sin(el), Math.cos(az) * Math.cos(el)];
  }

  skinPixel(u, v) { return this.project(this.skinDirection(u, v)); }
}

// The lens from GET /lens, else (a daemon without the route) the equidistant stand-in for width x height.
export async function loadLens(call, width, height) {
  try {
    const { data } = await call("GET", "/lens");
    if (data.model === "opencv_fisheye") return new Lens(data);
  } catch (err) {
    console.warn("no lens model from the blimp, using the equidistant stand-in:", err.message);
  }
  return Lens.equidistant(width, height);
}
