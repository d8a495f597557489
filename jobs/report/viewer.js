// SPDX-License-Identifier: MIT
// The splat viewer of the report page (`hbgs report`, gs/jobs/report.h): WebGL 2, no libraries,
// embedded into the page at build time. It draws the baked Gaussians the page carries (antimatter15
// .splat records, 32 bytes each, base64 in <script id="hbgs-splats">) from the dataset cameras or a
// free camera (drag: orbit, wheel: zoom, right drag or shift drag: pan).
//
// It follows hbgs's renderer (README "Conventions", core/render/renderer.cpp, simd/ref/*_ref.cpp)
// so that a screenshot from a dataset camera can be compared pixel for pixel with `hbgs render`:
//   - cameras: world-to-camera x_cam = R x_world + t, x right, y down, z forward; pixel centres at
//     (i + 0.5, j + 0.5), u = fx x / z + cx;
//   - near cull at z <= 0.2; EWA: cov2 = J W Sigma W^T J^T with the Jacobian evaluated at x/z, y/z
//     clamped to 1.3 x the image's extent, + 0.3 px^2 on the diagonal; det <= 0 culled;
//   - footprint: the square of radius ceil(3 sqrt(lambda_max)) px around the projected mean (hbgs
//     bins by the 16 px tiles that square touches; `&tiles=1` in the URL draws those tiles too);
//   - alpha = min(0.99, opacity exp(-0.5 d^T conic d)), dropped below 1/255 and where the exponent
//     is positive (rounding);
//   - order: by camera-space depth (hbgs blends front to back, ties by index); here back to front
//     with premultiplied colour and blend (ONE, ONE_MINUS_SRC_ALPHA) over the background colour,
//     which is the same sum;
//   - precision: blending runs in a float32 (or float16) colour buffer when the browser offers one
//     (EXT_color_buffer_float, EXT_float_blend), and the result is rounded once to 8 bits, as hbgs
//     rounds its float render (c * 255 + 0.5, truncated).
// The .splat decoding matches hbgs's reader (io/splat/antimatter_splat.cpp): colour = byte /
// 255; opacity = clamp(byte, 0.5, 254.5) / 255; rotation (w, x, y, z) = (byte - 128) / 128
// normalised (all zero: identity); scale linear.
//
// URL fragment: #view=NAME or #view=INDEX opens that dataset camera with the canvas at exactly its
// width x height (one canvas pixel per image pixel; the page's tests screenshot it). For
// comparisons: `&tiles=1` widens each footprint to hbgs's tile rectangle, `&blend=8bit` blends in
// the 8-bit canvas instead of the float buffer. window.hbgsViewer reports the
// state (ready, the view shown, the precision used, frames drawn) for scripts.
'use strict';

(function () {
  const status = document.getElementById('hbgs-viewer-status');
  const say = (text) => { if (status) status.textContent = text; };
  const viewerState = { ready: false, view: null, precision: null, frames: 0, splats: 0, error: null };
  window.hbgsViewer = viewerState;

  // ---- Data -------------------------------------------------------------------------------------
  const data = JSON.parse(document.getElementById('hbgs-data').textContent);
  const cameras = data.cameras;            // [{name, test, width, height, fx, fy, cx, cy, R[9], t[3]}]
  const background = data.background;      // [3] in [0, 1]
  const splatBytes = (function () {
    const text = document.getElementById('hbgs-splats').textContent.replace(/\s+/g, '');
    const binary = atob(text);
    const bytes = new Uint8Array(binary.length);
    for (let i = 0; i < binary.length; ++i) bytes[i] = binary.charCodeAt(i);
    return bytes;
  })();
  const kRecordBytes = 32;
  const splatCount = Math.floor(splatBytes.length / kRecordBytes);
  viewerState.splats = splatCount;

  // Per splat: mean [3], world covariance [6] (xx, xy, xz, yy, yz, zz), colour [3], opacity.
  const means = new Float32Array(3 * splatCount);
  const texelsPerSplat = 4;                // RGBA32F texels: (mean, opacity) (xx xy xz yy) (yz zz) (rgb)
  const splatsPerRow = 512;             // 2048 texels a row: WebGL 2's smallest MAX_TEXTURE_SIZE
  const textureWidth = splatsPerRow * texelsPerSplat;
  const textureRows = Math.max(1, Math.ceil(splatCount / splatsPerRow));
  const texels = new Float32Array(textureWidth * textureRows * 4);
  (function decodeSplats() {
    const view = new DataView(splatBytes.buffer);
    for (let i = 0; i < splatCount; ++i) {
      const at = i * kRecordBytes;
      const p = [view.getFloat32(at, true), view.getFloat32(at + 4, true), view.getFloat32(at + 8, true)];
      const s = [view.getFloat32(at + 12, true), view.getFloat32(at + 16, true), view.getFloat32(at + 20, true)];
      let w = (splatBytes[at + 28] - 128) / 128, x = (splatBytes[at + 29] - 128) / 128;
      let y = (splatBytes[at + 30] - 128) / 128, z = (splatBytes[at + 31] - 128) / 128;
      const norm = Math.hypot(w, x, y, z);
      if (norm > 0) { w /= norm; x /= norm; y /= norm; z /= norm; } else { w = 1; x = y = z = 0; }
      // Rotation matrix of (w, x, y, z), row-major; M = Rot diag(s); Sigma = M M^T.
      const r = [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)];
      const m = [r[0] * s[0], r[1] * s[1], r[2] * s[2], r[3] * s[0], r[4] * s[1], r[5] * s[2],
                 r[6] * s[0], r[7] * s[1], r[8] * s[2]];
      const cov = (a, b) => m[3 * a] * m[3 * b] + m[3 * a + 1] * m[3 * b + 1] + m[3 * a + 2] * m[3 * b + 2];
      const opacity = Math.min(Math.max(splatBytes[at + 27], 0.5), 254.5) / 255;
      const o = (Math.floor(i / splatsPerRow) * textureWidth + (i % splatsPerRow) * texelsPerSplat) * 4;
      texels.set([p[0], p[1], p[2], opacity,
                  cov(0, 0), cov(0, 1), cov(0, 2), cov(1, 1),
                  cov(1, 2), cov(2, 2), 0, 0,
                  splatBytes[at + 24] / 255, splatBytes[at + 25] / 255, splatBytes[at + 26] / 255, 0], o);
      means.set(p, 3 * i);
    }
  })();

  // Scene centre: the per-axis median of the splat means (robust to far-away floaters); the orbit
  // target sits at the depth of this point along the camera's viewing axis.
  const sceneCentre = (function () {
    const centre = [0, 0, 0];
    if (splatCount === 0) return centre;
    const step = Math.max(1, Math.floor(splatCount / 20000));
    for (let axis = 0; axis < 3; ++axis) {
      const values = [];
      for (let i = 0; i < splatCount; i += step) values.push(means[3 * i + axis]);
      values.sort((a, b) => a - b);
      centre[axis] = values[values.length >> 1];
    }
    return centre;
  })();

  // ---- Small 3-vector / 3x3 (row-major) helpers ----------------------------------------------------
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
  const normalize = (a) => { const n = Math.hypot(a[0], a[1], a[2]) || 1; return scale(a, 1 / n); };
  const row = (R, i) => [R[3 * i], R[3 * i + 1], R[3 * i + 2]];
  const mulMat = (A, B) => {
    const C = new Array(9);
    for (let i = 0; i < 3; ++i)
      for (let j = 0; j < 3; ++j) C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
    return C;
  };
  const transpose = (A) => [A[0], A[3], A[6], A[1], A[4], A[7], A[2], A[5], A[8]];
  // Rotation by angle (radians) about a unit axis (Rodrigues), row-major.
  const axisAngle = (k, angle) => {
    const c = Math.cos(angle), s = Math.sin(angle), v = 1 - c;
    return [c + k[0] * k[0] * v, k[0] * k[1] * v - k[2] * s, k[0] * k[2] * v + k[1] * s,
            k[1] * k[0] * v + k[2] * s, c + k[1] * k[1] * v, k[1] * k[2] * v - k[0] * s,
            k[2] * k[0] * v - k[1] * s, k[2] * k[1] * v + k[0] * s, c + k[2] * k[2] * v];
  };
  // Camera centre C = -R^T t.
  const centreOf = (R, t) => scale([R[0] * t[0] + R[3] * t[1] + R[6] * t[2],
                                    R[1] * t[0] + R[4] * t[1] + R[7] * t[2],
                                    R[2] * t[0] + R[5] * t[1] + R[8] * t[2]], -1);

  // "Up" for the turntable orbit: minus the mean of the dataset cameras' y axes (y points down in
  // the image), which is the capture's up direction for ordinary captures.
  const worldUp = (function () {
    let up = [0, 0, 0];
    for (const c of cameras) up = sub(up, row(c.R, 1));
    return Math.hypot(up[0], up[1], up[2]) > 1e-6 ? normalize(up) : [0, -1, 0];
  })();

  // ---- WebGL set-up ---------------------------------------------------------------------------------
  const canvas = document.getElementById('hbgs-canvas');
  const gl = canvas.getContext('webgl2', { alpha: false, antialias: false, depth: false, stencil: false,
                                           premultipliedAlpha: false, preserveDrawingBuffer: true });
  if (!gl) {
    viewerState.error = 'this browser offers no WebGL 2';
    say('The viewer needs WebGL 2, which this browser does not offer; the metrics and images above do not.');
    console.error('hbgs viewer: ' + viewerState.error);
    return;
  }

  const splatVertexShader = `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D u_splats;  // texelsPerSplat RGBA32F texels per splat, splatsPerRow per row
uniform mat3 u_R;                  // world-to-camera rotation
uniform vec3 u_t;                  // world-to-camera translation
uniform vec4 u_intrinsics;         // fx, fy, cx, cy (px)
uniform vec2 u_size;               // image width, height (px)
uniform vec4 u_limits;             // x/z clamp +, -, y/z clamp +, - for the EWA Jacobian
uniform int u_tiles;               // 1: widen the footprint to hbgs's 16 px tile rectangle
in vec2 a_corner;                  // quad corner in {-1, 1}^2
in uint a_index;                   // splat index (one instance per splat, back to front)
flat out vec2 v_mean;              // projected mean, px (y down)
flat out vec3 v_conic;             // inverse 2D covariance (a, b, c), px^-2
flat out vec4 v_colour;            // rgb, opacity
void main() {
  int i = int(a_index);
  ivec2 base = ivec2((i % ${splatsPerRow}) * ${texelsPerSplat}, i / ${splatsPerRow});
  vec4 t0 = texelFetch(u_splats, base, 0);
  vec4 t1 = texelFetch(u_splats, base + ivec2(1, 0), 0);
  vec4 t2 = texelFetch(u_splats, base + ivec2(2, 0), 0);
  vec4 t3 = texelFetch(u_splats, base + ivec2(3, 0), 0);
  gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // outside the clip volume: culled unless set below
  vec3 m = u_R * t0.xyz + u_t;
  if (!(m.z > 0.2)) return;               // hbgs's near plane
  mat3 sigma = mat3(t1.x, t1.y, t1.z, t1.y, t1.w, t2.x, t1.z, t2.x, t2.y);
  mat3 camSigma = u_R * sigma * transpose(u_R);
  float fx = u_intrinsics.x, fy = u_intrinsics.y;
  float tx = m.z * clamp(m.x / m.z, -u_limits.y, u_limits.x);
  float ty = m.z * clamp(m.y / m.z, -u_limits.w, u_limits.z);
  vec3 j0 = vec3(fx / m.z, 0.0, -fx * tx / (m.z * m.z));
  vec3 j1 = vec3(0.0, fy / m.z, -fy * ty / (m.z * m.z));
  vec3 s0 = camSigma * j0, s1 = camSigma * j1;
  float a = dot(j0, s0) + 0.3, b = dot(j0, s1), c = dot(j1, s1) + 0.3;
  float det = a * c - b * b;
  if (!(det > 0.0)) return;
  float mid = 0.5 * (a + c);
  float lambda = mid + sqrt(max(0.1, mid * mid - det));
  float radius = ceil(3.0 * sqrt(lambda));
  vec2 mean = vec2(fx * m.x / m.z + u_intrinsics.z, fy * m.y / m.z + u_intrinsics.w);
  vec2 lo = mean - radius, hi = mean + radius;
  if (u_tiles == 1) {
    // hbgs's tile rectangle (simd tile_rect): whole 16 px tiles, from the mean shifted by -0.5 px.
    vec2 tiles = ceil(u_size / 16.0);
    vec2 first = clamp(floor((mean - 0.5 - radius) / 16.0), vec2(0.0), tiles);
    vec2 last = clamp(floor((mean - 0.5 + radius + 15.0) / 16.0), vec2(0.0), tiles);
    lo = first * 16.0;
    hi = min(last * 16.0, u_size);
  }
  vec2 pixel = mix(lo, hi, 0.5 * (a_corner + 1.0));
  gl_Position = vec4(2.0 * pixel.x / u_size.x - 1.0, 1.0 - 2.0 * pixel.y / u_size.y, 0.0, 1.0);
  v_mean = mean;
  v_conic = vec3(c, -b, a) / det;
  v_colour = vec4(t3.rgb, t0.w);
}`;

  const splatFragmentShader = `#version 300 es
precision highp float;
uniform float u_height;
flat in vec2 v_mean;
flat in vec3 v_conic;
flat in vec4 v_colour;
out vec4 fragColour;
void main() {
  // gl_FragCoord is the pixel centre with y up; hbgs's pixel centres have y down.
  vec2 d = v_mean - vec2(gl_FragCoord.x, u_height - gl_FragCoord.y);
  float power = -0.5 * (v_conic.x * d.x * d.x + v_conic.z * d.y * d.y) - v_conic.y * d.x * d.y;
  if (power > 0.0) discard;
  float alpha = min(0.99, v_colour.a * exp(power));
  if (alpha < 1.0 / 255.0) discard;
  fragColour = vec4(v_colour.rgb * alpha, alpha);  // premultiplied
}`;

  // Copies the float accumulation buffer to the canvas, rounded once to 8 bits the way hbgs
  // rounds its renders.
  const resolveVertexShader = `#version 300 es
void main() {
  vec2 p = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID & 2) * 2 - 1));
  gl_Position = vec4(p, 0.0, 1.0);
}`;
  const resolveFragmentShader = `#version 300 es
precision highp float;
uniform highp sampler2D u_accumulated;
out vec4 fragColour;
void main() {
  vec3 c = clamp(texelFetch(u_accumulated, ivec2(gl_FragCoord.xy), 0).rgb, 0.0, 1.0);
  fragColour = vec4(floor(c * 255.0 + 0.5) / 255.0, 1.0);
}`;

  function compile(type, source) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error('shader: ' + gl.getShaderInfoLog(shader));
    return shader;
  }
  function link(vertexSource, fragmentSource) {
    const program = gl.createProgram();
    gl.attachShader(program, compile(gl.VERTEX_SHADER, vertexSource));
    gl.attachShader(program, compile(gl.FRAGMENT_SHADER, fragmentSource));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error('program: ' + gl.getProgramInfoLog(program));
    return program;
  }

  if (textureRows > gl.getParameter(gl.MAX_TEXTURE_SIZE)) {
    viewerState.error = `${splatCount} splats need a ${textureRows}-row texture; this GPU allows ` +
                        gl.getParameter(gl.MAX_TEXTURE_SIZE);
    say('The viewer cannot hold the splats: ' + viewerState.error + ' (hbgs report --max-splats lowers the count).');
    console.error('hbgs viewer: ' + viewerState.error);
    return;
  }
  let splatProgram, resolveProgram;
  try {
    splatProgram = link(splatVertexShader, splatFragmentShader);
    resolveProgram = link(resolveVertexShader, resolveFragmentShader);
  } catch (e) {
    viewerState.error = String(e.message || e);
    say('The viewer could not start: ' + viewerState.error);
    console.error('hbgs viewer: ' + viewerState.error);
    return;
  }
  const uniform = (program, name) => gl.getUniformLocation(program, name);
  const u = {
    splats: uniform(splatProgram, 'u_splats'), R: uniform(splatProgram, 'u_R'), t: uniform(splatProgram, 'u_t'),
    intrinsics: uniform(splatProgram, 'u_intrinsics'), size: uniform(splatProgram, 'u_size'),
    limits: uniform(splatProgram, 'u_limits'), tiles: uniform(splatProgram, 'u_tiles'),
    height: uniform(splatProgram, 'u_height'), accumulated: uniform(resolveProgram, 'u_accumulated'),
  };

  // The splat table, uploaded once.
  const splatTexture = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, splatTexture);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, textureWidth, textureRows, 0, gl.RGBA, gl.FLOAT, texels);

  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const cornerBuffer = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, cornerBuffer);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
  const cornerLocation = gl.getAttribLocation(splatProgram, 'a_corner');
  gl.enableVertexAttribArray(cornerLocation);
  gl.vertexAttribPointer(cornerLocation, 2, gl.FLOAT, false, 0, 0);
  const orderBuffer = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, orderBuffer);
  gl.bufferData(gl.ARRAY_BUFFER, 4 * Math.max(1, splatCount), gl.DYNAMIC_DRAW);
  const indexLocation = gl.getAttribLocation(splatProgram, 'a_index');
  gl.enableVertexAttribArray(indexLocation);
  gl.vertexAttribIPointer(indexLocation, 1, gl.UNSIGNED_INT, 0, 0);
  gl.vertexAttribDivisor(indexLocation, 1);
  gl.bindVertexArray(null);

  // The accumulation buffer: float32 when it can be blended (EXT_float_blend), else float16, else
  // none (the canvas's 8 bits, which round after every blend).
  const floatTargets = !!gl.getExtension('EXT_color_buffer_float');
  const floatBlend = floatTargets && !!gl.getExtension('EXT_float_blend');
  let accumulationFormat = floatBlend ? gl.RGBA32F : floatTargets ? gl.RGBA16F : null;
  viewerState.precision = floatBlend ? 'float32' : floatTargets ? 'float16' : '8-bit';
  let accumulation = null;  // {texture, framebuffer, width, height}
  let force8Bit = false;    // `&blend=8bit`: blend in the canvas itself (to measure what precision buys)
  function accumulationTarget(width, height) {
    if (!accumulationFormat || force8Bit) return null;
    if (accumulation && accumulation.width === width && accumulation.height === height) return accumulation;
    if (accumulation) { gl.deleteFramebuffer(accumulation.framebuffer); gl.deleteTexture(accumulation.texture); }
    const texture = gl.createTexture();
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texStorage2D(gl.TEXTURE_2D, 1, accumulationFormat, width, height);
    const framebuffer = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, framebuffer);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, texture, 0);
    const complete = gl.checkFramebufferStatus(gl.FRAMEBUFFER) === gl.FRAMEBUFFER_COMPLETE;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    if (!complete) {  // offered but not renderable here: blend in the canvas from now on
      gl.deleteFramebuffer(framebuffer);
      gl.deleteTexture(texture);
      accumulationFormat = null;
      return (accumulation = null);
    }
    return (accumulation = { texture, framebuffer, width, height });
  }

  // ---- Depth order ----------------------------------------------------------------------------------
  // Splats in front of the near plane, back to front: a stable LSD radix sort (4 x 8 bits) of the
  // float bits of the camera-space depth (positive here, so the bits order like the floats), front
  // to back with ties by index as hbgs, then reversed.
  const order = new Uint32Array(splatCount), scratch = new Uint32Array(splatCount);
  const keys = new Uint32Array(splatCount), scratchKeys = new Uint32Array(splatCount);
  const depthBits = new Float32Array(1), depthBitsU32 = new Uint32Array(depthBits.buffer);
  const counts = new Uint32Array(256);
  function sortBackToFront(R, t) {
    let n = 0;
    for (let i = 0; i < splatCount; ++i) {
      const z = R[6] * means[3 * i] + R[7] * means[3 * i + 1] + R[8] * means[3 * i + 2] + t[2];
      if (!(z > 0.2)) continue;
      depthBits[0] = z;
      keys[n] = depthBitsU32[0];
      order[n++] = i;
    }
    let inKeys = keys, inOrder = order, outKeys = scratchKeys, outOrder = scratch;
    for (let shift = 0; shift < 32; shift += 8) {
      counts.fill(0);
      for (let k = 0; k < n; ++k) ++counts[(inKeys[k] >>> shift) & 255];
      let sum = 0;
      for (let b = 0; b < 256; ++b) { const c = counts[b]; counts[b] = sum; sum += c; }
      for (let k = 0; k < n; ++k) {
        const at = counts[(inKeys[k] >>> shift) & 255]++;
        outKeys[at] = inKeys[k];
        outOrder[at] = inOrder[k];
      }
      [inKeys, outKeys] = [outKeys, inKeys];
      [inOrder, outOrder] = [outOrder, inOrder];
    }
    // Four passes: the sorted order is back in `order`.
    order.subarray(0, n).reverse();
    return n;
  }

  // ---- Camera -----------------------------------------------------------------------------------------
  // The camera drawn: pose (R row-major, t), intrinsics at the canvas's resolution, and the orbit
  // target. A dataset camera at scale k has fx k, cx k (pixel edges scale, centres follow).
  const camera = { R: null, t: null, fx: 0, fy: 0, cx: 0, cy: 0, width: 0, height: 0, target: null, viewIndex: -1 };
  let tilesMode = false;
  const select = document.getElementById('hbgs-view-select');

  function setCamera(index, scaleFactor) {
    const c = cameras[index];
    const k = scaleFactor;
    camera.R = c.R.slice();
    camera.t = c.t.slice();
    camera.width = Math.max(1, Math.round(c.width * k));
    camera.height = Math.max(1, Math.round(c.height * k));
    camera.fx = c.fx * k; camera.fy = c.fy * k; camera.cx = c.cx * k; camera.cy = c.cy * k;
    camera.viewIndex = index;
    const centre = centreOf(camera.R, camera.t);
    const forward = row(camera.R, 2);
    let depth = dot(sub(sceneCentre, centre), forward);
    if (!(depth > 1e-3)) depth = Math.max(1e-3, Math.hypot(...sub(sceneCentre, centre)));
    camera.target = add(centre, scale(forward, depth));
    canvas.width = camera.width;
    canvas.height = camera.height;
    canvas.style.width = camera.width + 'px';
    canvas.style.height = camera.height + 'px';
    viewerState.view = c.name;
    if (select) select.value = String(index);
    requestDraw();
  }

  function setPose(R, C) {
    camera.R = R;
    camera.t = scale([dot(row(R, 0), C), dot(row(R, 1), C), dot(row(R, 2), C)], -1);
    camera.viewIndex = -1;
    viewerState.view = null;
    if (select) select.value = '';
    requestDraw();
  }

  // Rotates the camera about an axis through the target: the centre moves on a sphere, the
  // orientation turns with it (camera-to-world R^T becomes Rot R^T).
  function orbit(axis, angle) {
    const rot = axisAngle(axis, angle);
    const C = centreOf(camera.R, camera.t);
    const d = sub(C, camera.target);
    const rd = [dot(row(rot, 0), d), dot(row(rot, 1), d), dot(row(rot, 2), d)];
    setPose(mulMat(camera.R, transpose(rot)), add(camera.target, rd));
  }

  // ---- Drawing --------------------------------------------------------------------------------------
  let drawPending = false;
  function requestDraw() {
    if (drawPending) return;
    drawPending = true;
    requestAnimationFrame(() => { drawPending = false; draw(); });
  }

  function draw() {
    const W = camera.width, H = camera.height;
    const n = sortBackToFront(camera.R, camera.t);
    gl.bindBuffer(gl.ARRAY_BUFFER, orderBuffer);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, order.subarray(0, n));
    const target = accumulationTarget(W, H);
    viewerState.precision = target ? (accumulationFormat === gl.RGBA32F ? 'float32' : 'float16') : '8-bit';
    gl.bindFramebuffer(gl.FRAMEBUFFER, target ? target.framebuffer : null);
    gl.viewport(0, 0, W, H);
    gl.clearColor(background[0], background[1], background[2], 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.useProgram(splatProgram);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, splatTexture);
    gl.uniform1i(u.splats, 0);
    gl.uniformMatrix3fv(u.R, true, camera.R);
    gl.uniform3fv(u.t, camera.t);
    gl.uniform4f(u.intrinsics, camera.fx, camera.fy, camera.cx, camera.cy);
    gl.uniform2f(u.size, W, H);
    gl.uniform1f(u.height, H);
    gl.uniform1i(u.tiles, tilesMode ? 1 : 0);
    // hbgs's Jacobian clamp (simd finish_project_params): 1.3 x the image's extent in x/z, y/z.
    const extra = 0.3;
    gl.uniform4f(u.limits, (W - camera.cx) / camera.fx + extra * 0.5 * W / camera.fx,
                 camera.cx / camera.fx + extra * 0.5 * W / camera.fx,
                 (H - camera.cy) / camera.fy + extra * 0.5 * H / camera.fy,
                 camera.cy / camera.fy + extra * 0.5 * H / camera.fy);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    gl.bindVertexArray(vao);
    if (n > 0) gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, n);
    gl.bindVertexArray(null);
    gl.disable(gl.BLEND);
    if (target) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.viewport(0, 0, W, H);
      gl.useProgram(resolveProgram);
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, target.texture);
      gl.uniform1i(u.accumulated, 1);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    }
    gl.finish();
    viewerState.frames += 1;
    viewerState.drawn = n;
    const name = camera.viewIndex >= 0 ? cameras[camera.viewIndex].name : 'free camera';
    say(`${name}: ${W} x ${H} px, ${n} of ${splatCount} splats in front of the camera, ` +
        `blending in ${viewerState.precision}${tilesMode ? ', hbgs tile footprints' : ''}`);
    viewerState.ready = true;
  }

  // ---- Controls -------------------------------------------------------------------------------------
  if (select) {
    const free = document.createElement('option');
    free.value = '';
    free.textContent = '(free camera)';
    free.disabled = true;
    select.appendChild(free);
    cameras.forEach((c, i) => {
      const option = document.createElement('option');
      option.value = String(i);
      option.textContent = `${c.name} (${c.test ? 'test' : 'train'}, ${c.width} x ${c.height})`;
      select.appendChild(option);
    });
    select.addEventListener('change', () => {
      if (select.value === '') return;
      // Enlarged for viewing: drop a #view fragment, which promises the camera's exact pixels.
      if (location.hash) history.replaceState(null, '', location.pathname + location.search);
      setCamera(Number(select.value), displayScale(Number(select.value)));
    });
  }

  // Outside #view mode the canvas is enlarged (intrinsics scaled) to fill up to the page's width.
  function displayScale(index) {
    const available = Math.min(960, (canvas.parentElement ? canvas.parentElement.clientWidth : 960) || 960);
    return Math.max(1, Math.min(4, Math.floor(available / cameras[index].width)));
  }

  let drag = null;  // {x, y, pan}
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('mousedown', (e) => {
    drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey };
    e.preventDefault();
  });
  window.addEventListener('mouseup', () => { drag = null; });
  window.addEventListener('mousemove', (e) => {
    if (!drag || !camera.R) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (drag.pan) {
      // Moves camera and target in the image plane; a pixel at the target's depth follows the mouse.
      const C = centreOf(camera.R, camera.t);
      const depth = Math.max(1e-3, dot(sub(camera.target, C), row(camera.R, 2)));
      const shift = add(scale(row(camera.R, 0), -dx * depth / camera.fx), scale(row(camera.R, 1), -dy * depth / camera.fy));
      camera.target = add(camera.target, shift);
      setPose(camera.R, add(C, shift));
    } else {
      // Turntable: yaw about the capture's up direction, pitch about the camera's x axis.
      orbit(worldUp, -dx * 0.005);
      orbit(row(camera.R, 0), dy * 0.005);
    }
  });
  canvas.addEventListener('wheel', (e) => {
    if (!camera.R) return;
    e.preventDefault();
    const C = centreOf(camera.R, camera.t);
    const factor = Math.exp(Math.max(-1, Math.min(1, e.deltaY * 0.001)));
    setPose(camera.R, add(camera.target, scale(sub(C, camera.target), factor)));
  }, { passive: false });
  const reset = document.getElementById('hbgs-view-reset');
  if (reset) reset.addEventListener('click', () => openFromLocation(true));

  // ---- URL fragment: #view=NAME or #view=INDEX [&tiles=1] ----------------------------------------
  function openFromLocation(fallBack) {
    const params = new URLSearchParams(location.hash.replace(/^#/, ''));
    tilesMode = params.get('tiles') === '1';
    force8Bit = params.get('blend') === '8bit';
    const wanted = params.get('view');
    if (wanted !== null) {
      let index = cameras.findIndex((c) => c.name === wanted);
      if (index < 0 && /^\d+$/.test(wanted) && Number(wanted) < cameras.length) index = Number(wanted);
      if (index >= 0) {
        setCamera(index, 1);  // exactly the camera's pixels
        return;
      }
      say(`No dataset view is named "${wanted}"; showing the first test view.`);
      console.warn('hbgs viewer: no view ' + wanted);
    }
    if (fallBack || camera.R === null) {
      const first = Math.max(0, data.initial_view || 0);
      if (cameras.length > 0) setCamera(first, displayScale(first));
    }
  }
  window.addEventListener('hashchange', () => openFromLocation(false));
  if (cameras.length === 0) {
    say('The run\'s dataset has no cameras to view from.');
    return;
  }
  openFromLocation(true);
})();
