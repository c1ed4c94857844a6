// treecal report.html: a small 3D view of the robot at one measured configuration, drawn on a
// canvas with an orthographic projection (no library). Data: the JSON in #scene-data
// (report::html::Scene). Sets data-viewer="ready" on <body> once drawn.
(function () {
  'use strict';
  var scene = JSON.parse(document.getElementById('scene-data').textContent);
  var canvas = document.getElementById('viewer');
  var select = document.getElementById('viewer-configuration');
  var scaleSelect = document.getElementById('viewer-scale');
  var status = document.getElementById('viewer-status');
  var context = canvas.getContext('2d');
  var view = { yaw: -0.7, pitch: 0.35, zoom: 1.0 };

  scene.configurations.forEach(function (c, index) {
    var option = document.createElement('option');
    option.value = String(index);
    option.textContent = c.id + ' (' + c.set + ', ' + c.tool + ', ' + c.error_mm.toFixed(3) + ' mm' +
      (c.outlier ? ', outlier' : '') + ')';
    select.appendChild(option);
  });

  // World point -> [screen x, screen y, depth]: turn about z (yaw), tilt about x (pitch).
  function project(p, center, scale) {
    var x = p[0] - center[0], y = p[1] - center[1], z = p[2] - center[2];
    var cy = Math.cos(view.yaw), sy = Math.sin(view.yaw);
    var x1 = cy * x - sy * y, y1 = sy * x + cy * y;
    var cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    var y2 = cp * y1 - sp * z, z2 = sp * y1 + cp * z;
    return [canvas.width / 2 + scale * x1, canvas.height / 2 - scale * z2, y2];
  }

  function bounds(c) {
    var all = c.points.concat([c.predicted, c.measured]);
    var low = all[0].slice(), high = all[0].slice();
    all.forEach(function (p) {
      for (var k = 0; k < 3; k++) { low[k] = Math.min(low[k], p[k]); high[k] = Math.max(high[k], p[k]); }
    });
    var center = [0, 1, 2].map(function (k) { return (low[k] + high[k]) / 2; });
    var size = Math.max(high[0] - low[0], high[1] - low[1], high[2] - low[2], 1e-3);
    return { center: center, size: size };
  }

  function line(a, b, colour, width) {
    context.strokeStyle = colour;
    context.lineWidth = width;
    context.beginPath();
    context.moveTo(a[0], a[1]);
    context.lineTo(b[0], b[1]);
    context.stroke();
  }

  function draw() {
    context.clearRect(0, 0, canvas.width, canvas.height);
    if (scene.configurations.length === 0) {
      status.textContent = 'no configuration to show';
      return;
    }
    var c = scene.configurations[Number(select.value) || 0];
    var box = bounds(c);
    var scale = view.zoom * 0.8 * Math.min(canvas.width, canvas.height) / box.size;
    var at = function (p) { return project(p, box.center, scale); };
    var points = c.points.map(at);
    // Base axes (x red, y green, z blue), a tenth of the robot's size.
    var base = c.points[0], axis = box.size / 10;
    [[1, 0, 0, '#D55E00'], [0, 1, 0, '#009E73'], [0, 0, 1, '#0072B2']].forEach(function (a) {
      line(points[0], at([base[0] + a[0] * axis, base[1] + a[1] * axis, base[2] + a[2] * axis]), a[3], 1);
    });
    scene.parents.forEach(function (parent, index) {
      if (parent !== null) { line(points[parent], points[index], '#444', 3); }
    });
    points.forEach(function (p, index) {
      context.fillStyle = index === 0 ? '#222' : '#666';
      var r = index === 0 ? 6 : 3;
      if (index === 0) { context.fillRect(p[0] - r, p[1] - r, 2 * r, 2 * r); } else {
        context.beginPath(); context.arc(p[0], p[1], r, 0, 2 * Math.PI); context.fill();
      }
    });
    var predicted = at(c.predicted);
    line(points[c.tool_parent], predicted, '#444', 2);
    var k = Number(scaleSelect.value) || 1;
    var shown = at([0, 1, 2].map(function (i) { return c.predicted[i] + k * (c.measured[i] - c.predicted[i]); }));
    line(predicted, shown, '#E69F00', 1.5);
    context.fillStyle = '#0072B2';
    context.beginPath(); context.arc(predicted[0], predicted[1], 6, 0, 2 * Math.PI); context.fill();
    line([shown[0] - 6, shown[1] - 6], [shown[0] + 6, shown[1] + 6], '#D55E00', 3);
    line([shown[0] - 6, shown[1] + 6], [shown[0] + 6, shown[1] - 6], '#D55E00', 3);
    status.textContent = 'row ' + c.id + ': measured − predicted = ' + c.error_mm.toFixed(3) +
      ' mm (drawn ×' + k + ')';
  }

  var drag = null;
  canvas.addEventListener('mousedown', function (e) { drag = [e.clientX, e.clientY]; });
  window.addEventListener('mouseup', function () { drag = null; });
  window.addEventListener('mousemove', function (e) {
    if (!drag) { return; }
    view.yaw += (e.clientX - drag[0]) * 0.01;
    view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY];
    draw();
  });
  canvas.addEventListener('wheel', function (e) {
    e.preventDefault();
    view.zoom = Math.max(0.2, Math.min(20, view.zoom * (e.deltaY < 0 ? 1.1 : 1 / 1.1)));
    draw();
  }, { passive: false });
  select.addEventListener('change', draw);
  scaleSelect.addEventListener('change', draw);
  draw();
  document.body.setAttribute('data-viewer', 'ready');
})();
