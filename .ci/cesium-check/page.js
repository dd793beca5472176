// The browser side of view.mjs: a bare CesiumJS scene (no globe, imagery, terrain, sky, sun,
// moon, fog, anti-aliasing or Ion) over a flat background colour, holding one tileset, with the
// camera set from citywalk's local-frame poses. view.mjs drives it through window.citywalk.
/* global Cesium */
'use strict';

window.citywalk = (() => {
  const errors = [];
  let widget;
  let tileset;
  let rootTransform;

  const tick = () => new Promise((resolve) => setTimeout(resolve, 0));

  // A citywalk pose [x, y, z, yaw_deg, pitch_deg] (metres, x east, y north, z up; yaw
  // counter-clockwise from east, pitch > 0 up) as a Cesium camera: the tileset's root
  // transform takes the local frame to ECEF, so it takes the eye and the view axes too.
  function setPose([x, y, z, yawDeg, pitchDeg]) {
    const yaw = Cesium.Math.toRadians(yawDeg);
    const pitch = Cesium.Math.toRadians(pitchDeg);
    const forward = new Cesium.Cartesian3(
      Math.cos(yaw) * Math.cos(pitch),
      Math.sin(yaw) * Math.cos(pitch),
      Math.sin(pitch),
    );
    const right = new Cesium.Cartesian3(Math.sin(yaw), -Math.cos(yaw), 0);
    const up = Cesium.Cartesian3.cross(right, forward, new Cesium.Cartesian3());
    const m = rootTransform;
    const axis = (v) =>
      Cesium.Cartesian3.normalize(
        Cesium.Matrix4.multiplyByPointAsVector(m, v, new Cesium.Cartesian3()),
        new Cesium.Cartesian3(),
      );
    widget.scene.camera.setView({
      destination: Cesium.Matrix4.multiplyByPoint(m, new Cesium.Cartesian3(x, y, z), new Cesium.Cartesian3()),
      orientation: {direction: axis(forward), up: axis(up)},
    });
  }

  // Renders until every tile the view needs is loaded (or `limitMs` passed); the frames count.
  async function settle(limitMs) {
    const start = performance.now();
    let frames = 0;
    for (;;) {
      widget.render();
      frames += 1;
      if (tileset.tilesLoaded && frames > 2) return {frames, ms: performance.now() - start, loaded: true};
      if (performance.now() - start > limitMs) return {frames, ms: performance.now() - start, loaded: false};
      await tick();
    }
  }

  // One frame drawn and finished: render, then a one-pixel readback that waits for the GL
  // command stream (SwiftShader in Chromium's GPU process) to complete.
  const pixel = new Uint8Array(4);
  function timedFrame() {
    const gl = widget.scene.context._gl;
    const t0 = performance.now();
    widget.render();
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    return performance.now() - t0;
  }

  return {
    errors,
    // opts: {tileset URL, transform (16 numbers, column-major), fovYDeg, background [r,g,b] in
    // 0..1, maximumScreenSpaceError}
    async setup(opts) {
      window.addEventListener('error', (e) => errors.push(`page: ${e.message}`));
      window.addEventListener('unhandledrejection', (e) => errors.push(`page: ${e.reason}`));
      Cesium.Ion.defaultAccessToken = '';
      widget = new Cesium.CesiumWidget('view', {
        baseLayer: false,
        terrainProvider: new Cesium.EllipsoidTerrainProvider(),
        skyBox: false,
        skyAtmosphere: false,
        useDefaultRenderLoop: false,
        msaaSamples: 1,
        shadows: false,
        contextOptions: {webgl: {antialias: false, preserveDrawingBuffer: true, alpha: false}},
      });
      const scene = widget.scene;
      scene.globe.show = false;
      scene.fog.enabled = false;
      if (scene.sun) scene.sun.show = false;
      if (scene.moon) scene.moon.show = false;
      scene.highDynamicRange = false;
      scene.postProcessStages.fxaa.enabled = false;
      scene.backgroundColor = new Cesium.Color(...opts.background, 1.0);
      scene.renderError.addEventListener((_, e) => errors.push(`render: ${e}`));
      rootTransform = Cesium.Matrix4.fromArray(opts.transform);
      const aspect = scene.canvas.width / scene.canvas.height;
      // Cesium's fov is the wider of the two: the horizontal one for a landscape frame.
      const halfY = Cesium.Math.toRadians(opts.fovYDeg) / 2;
      scene.camera.frustum.fov = aspect >= 1 ? 2 * Math.atan(Math.tan(halfY) * aspect) : 2 * halfY;
      tileset = await Cesium.Cesium3DTileset.fromUrl(opts.tileset, {
        maximumScreenSpaceError: opts.maximumScreenSpaceError,
      });
      tileset.tileFailed.addEventListener((e) => errors.push(`tileFailed ${e.url}: ${e.message}`));
      scene.primitives.add(tileset);
      const gl = scene.context._gl;
      const info = gl.getExtension('WEBGL_debug_renderer_info');
      return {
        canvas: [scene.canvas.width, scene.canvas.height],
        fov_deg: Cesium.Math.toDegrees(scene.camera.frustum.fov),
        renderer: info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER),
      };
    },
    // The frame of one pose, once its tiles are loaded, as a PNG data URL.
    async shot(pose, limitMs) {
      setPose(pose);
      const settled = await settle(limitMs);
      widget.render();
      return {settled, png: widget.scene.canvas.toDataURL('image/png')};
    },
    // Per pose: the tiles loaded (not timed), then `repeat` finished frames timed; the median.
    async play(poses, sse, repeat, limitMs) {
      tileset.maximumScreenSpaceError = sse;
      const frames = [];
      for (const pose of poses) {
        setPose(pose);
        const settled = await settle(limitMs);
        const times = [];
        for (let i = 0; i < repeat; i++) times.push(timedFrame());
        times.sort((a, b) => a - b);
        frames.push({ms: times[Math.floor(times.length / 2)], settle_ms: settled.ms, loaded: settled.loaded});
      }
      return frames;
    },
  };
})();
