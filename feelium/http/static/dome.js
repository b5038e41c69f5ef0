// The fisheye image on a dome around the viewer, in plain WebGL 1 (no library: the blimp serves the page offline).
// The dome is a sphere cap of unit directions; each vertex's texture coordinate is where the lens model puts that
// direction in the fisheye image, so the image is undistorted by the lens model itself (and a marker drawn into
// the image lands where that direction is). The same renderer draws the page's canvas (a virtual camera the
// wearer turns by dragging) and each eye of an immersive WebXR session.

const VERTEX = `
attribute vec3 dir;      // unit direction, WebGL world axes (x right, y up, -z forward)
attribute vec2 tex;      // where the lens model puts it in the fisheye image (0..1)
uniform mat4 proj, view;
varying vec2 uv;
void main() {
  uv = tex;
  gl_Position = proj * view * vec4(dir * 50.0, 1.0);
}`;
const FRAGMENT = `
precision mediump float;
uniform sampler2D image;
varying vec2 uv;
void main() {
  // beyond the image: black, as the lens's own surround
  if (uv.x < 0.0 || uv.x > 1.0 || uv.y < 0.0 || uv.y > 1.0) { gl_FragColor = vec4(0.0, 0.0, 0.0, 1.0); return; }
  gl_FragColor = texture2D(image, uv);
}`;

const RINGS = 48, SEGMENTS = 96;

// --- 4x4 matrices, column-major as WebGL wants them ---
export function perspective(fovyRad, aspect, near, far) {
  const f = 1 / Math.tan(fovyRad / 2), nf = 1 / (near - far);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
}

// The view matrix of a camera turned by yaw (positive: to the right) and pitch (positive: up).
export function lookAround(yaw, pitch) {
  const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
  // the inverse (= transpose) of the camera's rotation Ry(-yaw) * Rx(pitch), i.e. Rx(-pitch) * Ry(yaw)
  return new Float32Array([cy, -sp * sy, -cp * sy, 0, 0, cp, -sp, 0, sy, sp * cy, cp * cy, 0, 0, 0, 0, 1]);
}

// An XR view's matrix without its translation: the dome is the far world, centred on the head wherever it moves.
export function rotationOnly(matrix) {
  const m = Float32Array.from(matrix);
  m[12] = 0; m[13] = 0; m[14] = 0;
  return m;
}

export class Dome {
  constructor(gl) {
    this.gl = gl;
    const prog = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, VERTEX], [gl.FRAGMENT_SHADER, FRAGMENT]]) {
      const s = gl.createShader(type);
      gl.shaderSource(s, src); gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      gl.attachShader(prog, s);
    }
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
    this.prog = prog;
    this.loc = { dir: gl.getAttribLocation(prog, "dir"), tex: gl.getAttribLocation(prog, "tex"),
      proj: gl.getUniformLocation(prog, "proj"), view: gl.getUniformLocation(prog, "view") };
    this.dirBuffer = gl.createBuffer(); this.texBuffer = gl.createBuffer(); this.indexBuffer = gl.createBuffer();
    this.texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    // a 640x480 frame is no power of two: WebGL 1 then allows only clamped, unmipmapped sampling
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    this.count = 0;
  }

  // Build the cap for a lens: rings of constant angle off the optical axis out to the widest the image shows.
  setLens(lens) {
    const gl = this.gl, dirs = [], texs = [], index = [];
    for (let i = 0; i <= RINGS; i++) {
      const theta = (lens.maxTheta * i) / RINGS;
      for (let j = 0; j <= SEGMENTS; j++) {
        const phi = (2 * Math.PI * j) / SEGMENTS;
        const cam = [Math.sin(theta) * Math.cos(phi), Math.sin(theta) * Math.sin(phi), Math.cos(theta)];
        dirs.push(cam[0], -cam[1], -cam[2]); // camera (x right, y down, z forward) -> WebGL world
        const [px, py] = lens.project(cam);
        // +0.5: pixel centres are integers in the lens model, texture coordinates run over pixel edges
        texs.push((px + 0.5) / lens.width, (py + 0.5) / lens.height);
      }
    }
    for (let i = 0; i < RINGS; i++) {
      for (let j = 0; j < SEGMENTS; j++) {
        const a = i * (SEGMENTS + 1) + j, b = a + SEGMENTS + 1;
        index.push(a, b, a + 1, a + 1, b, b + 1);
      }
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, this.dirBuffer); gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(dirs), gl.STATIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.texBuffer); gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(texs), gl.STATIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.indexBuffer);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint16Array(index), gl.STATIC_DRAW);
    this.count = index.length;
  }

  // The fisheye frame (with its markers) as the dome's texture, once per displayed frame.
  upload(source) {
    const gl = this.gl;
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, source);
  }

  // Draw into the bound framebuffer's viewport [x, y, w, h] with a projection and a (rotation-only) view.
  draw(viewport, proj, view) {
    const gl = this.gl, loc = this.loc;
    gl.viewport(...viewport);
    gl.useProgram(this.prog);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.dirBuffer);
    gl.enableVertexAttribArray(loc.dir); gl.vertexAttribPointer(loc.dir, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.texBuffer);
    gl.enableVertexAttribArray(loc.tex); gl.vertexAttribPointer(loc.tex, 2, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.indexBuffer);
    gl.uniformMatrix4fv(loc.proj, false, proj); gl.uniformMatrix4fv(loc.view, false, view);
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    gl.drawElements(gl.TRIANGLES, this.count, gl.UNSIGNED_SHORT, 0);
  }
}
