// The report page's player: frames.json (embedded as #frames-data) drawn on a canvas — true
// positions and trails, each directed edge's estimate of the neighbour (z_i − x̂_ij) with its
// 1σ ellipse, lost links dashed, departed agents grey, the target formation where there is one.
// Plain JavaScript, no dependencies (DecompressionStream: Chromium 80, Firefox 113, Safari
// 16.4); keyboard: Space play/pause, ←/→ a frame, Home/End.
(function () {
  'use strict';
  var holder = document.getElementById('frames-data');
  var root = document.getElementById('player');
  if (!holder || !root) { return; }
  // frames.json, gzipped and base64-encoded in the page: the browser inflates it.
  var bin = atob(holder.textContent.trim()), bytes = new Uint8Array(bin.length);
  for (var b = 0; b < bin.length; b++) { bytes[b] = bin.charCodeAt(b); }
  var inflated = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('gzip'));
  new Response(inflated).text().then(function (text) { start(JSON.parse(text)); })
    .catch(function (e) { setTimeout(function () { throw e; }); });

  function start(data) {
    var D = data.dim, N = data.agents, M = data.edges.length, T = D * (D + 1) / 2;
    var times = data.steps.map(function (k) { return k * data.dt; });
    var el = function (id) { return document.getElementById(id); };
    var canvas = el('player-canvas'), ctx = canvas.getContext('2d');
    var ui = {
      play: el('player-play'), time: el('player-time'), clock: el('player-clock'),
      speed: el('player-speed'), est: el('player-est'), run: el('player-run'),
      view: el('player-view'), scale: el('player-scale'), link: el('player-link'),
      status: el('player-status')
    };
    var PALETTE = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#17becf', '#8c564b',
      '#e377c2', '#7f7f7f', '#bcbd22'];
    var state = { est: 0, run: 0, frame: 0, t: 0, playing: false, timer: null, axes: [0, 1],
      scale: 1, bounds: null };

    function option(select, value, text) {
      var o = document.createElement('option');
      o.value = String(value); o.textContent = text; select.appendChild(o);
    }
    data.estimators.forEach(function (e, i) {
      option(ui.est, i, e.label + (e.label === e.kind ? '' : ' (' + e.kind + ')'));
    });
    if (D === 3) {
      option(ui.view, '0,1', 'x–y (top)'); option(ui.view, '0,2', 'x–z (front)');
      option(ui.view, '1,2', 'y–z (side)');
    } else {
      ui.view.parentNode.style.display = 'none';
    }
    // The reverse of each directed edge (−1 when the graph has only one direction).
    var reverse = data.edges.map(function (ij) {
      for (var q = 0; q < M; q++) { if (data.edges[q][0] === ij[1] && data.edges[q][1] === ij[0]) { return q; } }
      return -1;
    });
    function current() { return data.estimators[state.est].runs[state.run]; }
    function fillRuns() {
      var keep = ui.run.value;
      while (ui.run.firstChild) { ui.run.removeChild(ui.run.firstChild); }
      data.estimators[state.est].runs.forEach(function (r, i) { option(ui.run, i, 'run ' + r.run); });
      if (keep && Number(keep) < ui.run.options.length) { ui.run.value = keep; }
      state.run = Number(ui.run.value || 0);
    }
    function frames() { var r = current(); return r ? r.frames : 0; }

    // Bounds of the true positions and target of the shown run (all frames, this view), so that
    // frames of one run share a scale.
    function bounds() {
      var r = current(), a = state.axes, lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
      function add(p, i) {
        for (var c = 0; c < 2; c++) {
          var v = p[i * D + a[c]];
          if (v !== null && isFinite(v)) { lo[c] = Math.min(lo[c], v); hi[c] = Math.max(hi[c], v); }
        }
      }
      if (r) {
        r.positions.forEach(function (p) { for (var i = 0; i < N; i++) { add(p, i); } });
      }
      if (data.target) {
        data.target.forEach(function (p) { for (var i = 0; i < N; i++) { add(p, i); } });
      }
      if (!isFinite(lo[0])) { lo = [-1, -1]; hi = [1, 1]; }
      var span = Math.max(hi[0] - lo[0], hi[1] - lo[1], 1e-9), pad = 0.08 * span;
      state.bounds = { lo: [lo[0] - pad, lo[1] - pad], hi: [hi[0] + pad, hi[1] + pad] };
    }

    var margin = { l: 64, r: 16, t: 30, b: 46 };
    function transform() {
      var b = state.bounds, w = canvas.width - margin.l - margin.r, h = canvas.height - margin.t - margin.b;
      var s = Math.min(w / (b.hi[0] - b.lo[0]), h / (b.hi[1] - b.lo[1]));
      var ox = margin.l + (w - s * (b.hi[0] - b.lo[0])) / 2, oy = margin.t + (h + s * (b.hi[1] - b.lo[1])) / 2;
      return { s: s, x: function (v) { return ox + s * (v - b.lo[0]); }, y: function (v) { return oy - s * (v - b.lo[1]); } };
    }
    function niceStep(span) {
      var raw = span / 6, p = Math.pow(10, Math.floor(Math.log10(raw))), m = raw / p;
      return p * (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10);
    }
    function axes(tr) {
      var b = state.bounds, names = ['x', 'y', 'z'];
      ctx.strokeStyle = '#e6e6e6'; ctx.fillStyle = '#444'; ctx.lineWidth = 1; ctx.font = '12px sans-serif';
      for (var c = 0; c < 2; c++) {
        var st = niceStep(b.hi[c] - b.lo[c]);
        for (var v = Math.ceil(b.lo[c] / st) * st; v <= b.hi[c]; v += st) {
          ctx.beginPath();
          if (c === 0) {
            ctx.moveTo(tr.x(v), margin.t); ctx.lineTo(tr.x(v), canvas.height - margin.b); ctx.stroke();
            ctx.textAlign = 'center'; ctx.fillText(+v.toPrecision(6), tr.x(v), canvas.height - margin.b + 16);
          } else {
            ctx.moveTo(margin.l, tr.y(v)); ctx.lineTo(canvas.width - margin.r, tr.y(v)); ctx.stroke();
            ctx.textAlign = 'right'; ctx.fillText(+v.toPrecision(6), margin.l - 6, tr.y(v) + 4);
          }
        }
      }
      ctx.textAlign = 'center'; ctx.font = '13px sans-serif';
      ctx.fillText(names[state.axes[0]] + ' [m]', margin.l + (canvas.width - margin.l - margin.r) / 2, canvas.height - 8);
      ctx.save(); ctx.translate(16, margin.t + (canvas.height - margin.t - margin.b) / 2); ctx.rotate(-Math.PI / 2);
      ctx.fillText(names[state.axes[1]] + ' [m]', 0, 0); ctx.restore();
    }
    function colour(i) { return PALETTE[i % PALETTE.length]; }
    function cov(c, e, a, b) {
      if (a > b) { var t = a; a = b; b = t; }
      return c[e * T + a * D - a * (a - 1) / 2 + (b - a)];
    }
    // The 1σ ellipse of the 2 × 2 block [[p, q], [q, r]] (m²), scaled.
    function ellipse(tr, x, y, p, q, r) {
      if (p === null || q === null || r === null) { return; }
      var m = (p + r) / 2, d = Math.sqrt(Math.max(0, (p - r) * (p - r) / 4 + q * q));
      var l1 = Math.max(0, m + d), l2 = Math.max(0, m - d), ang = 0.5 * Math.atan2(2 * q, p - r);
      var rx = state.scale * Math.sqrt(l1) * tr.s, ry = state.scale * Math.sqrt(l2) * tr.s;
      ctx.beginPath(); ctx.ellipse(tr.x(x), tr.y(y), Math.max(rx, 0.5), Math.max(ry, 0.5), -ang, 0, 2 * Math.PI);
      ctx.stroke();
    }

    function draw() {
      var r = current(), f = state.frame, a = state.axes;
      ctx.clearRect(0, 0, canvas.width, canvas.height);
      ctx.fillStyle = '#fff'; ctx.fillRect(0, 0, canvas.width, canvas.height);
      if (!r || r.frames === 0) { return; }
      var tr = transform(), z = r.positions[f], xh = r.estimates[f], c = r.covariances[f];
      var seen = r.observed[f], here = r.present[f];
      axes(tr);
      if (data.target) {
        var tz = data.target[Math.min(f, data.target.length - 1)];
        ctx.strokeStyle = '#9a9a9a'; ctx.lineWidth = 1.2;
        for (var i = 0; i < N; i++) {
          var tx = tr.x(tz[i * D + a[0]]), ty = tr.y(tz[i * D + a[1]]);
          ctx.beginPath(); ctx.moveTo(tx - 5, ty - 5); ctx.lineTo(tx + 5, ty + 5);
          ctx.moveTo(tx - 5, ty + 5); ctx.lineTo(tx + 5, ty - 5); ctx.stroke();
        }
      }
      // Trails: the true path so far.
      ctx.lineWidth = 1; ctx.globalAlpha = 0.35;
      for (var i2 = 0; i2 < N; i2++) {
        ctx.strokeStyle = colour(i2); ctx.beginPath();
        for (var g = 0; g <= f; g++) {
          var p = r.positions[g], px = tr.x(p[i2 * D + a[0]]), py = tr.y(p[i2 * D + a[1]]);
          if (g === 0) { ctx.moveTo(px, py); } else { ctx.lineTo(px, py); }
        }
        ctx.stroke();
      }
      ctx.globalAlpha = 1;
      // Links: solid where measured this step, dashed where lost (either direction).
      var lost = 0;
      for (var e = 0; e < M; e++) {
        var ij = data.edges[e], i3 = ij[0], j3 = ij[1];
        if (seen[e] !== '1') { lost++; }
        var back = reverse[e];
        if (back >= 0 && i3 > j3) { continue; }
        var ok = seen[e] === '1' && (back < 0 || seen[back] === '1');
        var gone = here[i3] !== '1' || here[j3] !== '1';
        ctx.strokeStyle = gone ? '#d0d0d0' : ok ? '#8a8a8a' : '#c0392b';
        ctx.lineWidth = ok ? 1.2 : 1.6;
        ctx.setLineDash(ok ? [] : [6, 4]);
        ctx.beginPath(); ctx.moveTo(tr.x(z[i3 * D + a[0]]), tr.y(z[i3 * D + a[1]]));
        ctx.lineTo(tr.x(z[j3 * D + a[0]]), tr.y(z[j3 * D + a[1]])); ctx.stroke();
      }
      ctx.setLineDash([]);
      // The estimated formation: each edge as its owner estimates it, from z_i to z_i − x̂_ij.
      ctx.lineWidth = 1; ctx.globalAlpha = 0.45;
      for (var e1 = 0; e1 < M; e1++) {
        var o1 = data.edges[e1][0];
        if (here[o1] !== '1' || xh[e1 * D] === null) { continue; }
        var zx = z[o1 * D + a[0]], zy = z[o1 * D + a[1]];
        ctx.strokeStyle = colour(o1); ctx.beginPath(); ctx.moveTo(tr.x(zx), tr.y(zy));
        ctx.lineTo(tr.x(zx - xh[e1 * D + a[0]]), tr.y(zy - xh[e1 * D + a[1]])); ctx.stroke();
      }
      ctx.globalAlpha = 1;
      // Agents: leaders square, departed hollow grey.
      var away = 0;
      for (var i4 = 0; i4 < N; i4++) {
        var x4 = tr.x(z[i4 * D + a[0]]), y4 = tr.y(z[i4 * D + a[1]]), present = here[i4] === '1';
        if (!present) { away++; }
        ctx.fillStyle = present ? colour(i4) : '#ffffff'; ctx.strokeStyle = present ? '#222' : '#9a9a9a';
        ctx.lineWidth = 1.2; ctx.beginPath();
        if (data.leaders.indexOf(i4) >= 0) { ctx.rect(x4 - 6, y4 - 6, 12, 12); } else { ctx.arc(x4, y4, 6, 0, 2 * Math.PI); }
        ctx.fill(); ctx.stroke();
        if (N <= 30) { ctx.fillStyle = '#222'; ctx.font = '11px sans-serif'; ctx.textAlign = 'left'; ctx.fillText(String(i4), x4 + 7, y4 - 7); }
      }
      // Estimates (over the agents): agent i's estimate of neighbour j, z_i − x̂_ij, with its ellipse.
      for (var e2 = 0; e2 < M; e2++) {
        var own = data.edges[e2][0];
        if (here[own] !== '1' || xh[e2 * D] === null) { continue; }
        var ex = z[own * D + a[0]] - xh[e2 * D + a[0]], ey = z[own * D + a[1]] - xh[e2 * D + a[1]];
        ctx.strokeStyle = colour(own); ctx.fillStyle = colour(own); ctx.lineWidth = 1;
        ctx.globalAlpha = 0.8;
        ellipse(tr, ex, ey, cov(c, e2, a[0], a[0]), cov(c, e2, a[0], a[1]), cov(c, e2, a[1], a[1]));
        ctx.beginPath(); ctx.arc(tr.x(ex), tr.y(ey), 2.2, 0, 2 * Math.PI); ctx.fill();
        ctx.globalAlpha = 1;
      }
      var est = data.estimators[state.est];
      ctx.fillStyle = '#222'; ctx.font = '13px sans-serif'; ctx.textAlign = 'left';
      ctx.fillText('t = ' + times[f].toFixed(2) + ' s (step ' + data.steps[f] + ') · ' + est.label + ' · run ' + r.run +
        ' · ' + lost + ' of ' + M + ' directed links lost · ' + away + ' agent(s) departed', margin.l, 18);
      ui.clock.textContent = 't = ' + times[f].toFixed(2) + ' s';
      ui.time.value = String(f);
      var hash = '#t=' + times[f].toFixed(3).replace(/\.?0+$/, '') + '&run=' + r.run + '&est=' + encodeURIComponent(est.label) +
        (D === 3 ? '&view=' + state.axes.join(',') : '');
      ui.link.setAttribute('href', hash);
      root.setAttribute('data-frame', String(f));
      root.setAttribute('data-estimator', est.label);
      root.setAttribute('data-run', String(r.run));
    }

    function setFrame(f) {
      state.frame = Math.max(0, Math.min(frames() - 1, f));
      state.t = times[state.frame];
      draw();
    }
    function frameAt(t) {
      var f = 0;
      while (f + 1 < frames() && times[f + 1] <= t + 1e-9) { f++; }
      return f;
    }
    function stop() {
      state.playing = false; ui.play.textContent = 'Play'; ui.play.setAttribute('aria-pressed', 'false');
      if (state.timer) { clearInterval(state.timer); state.timer = null; }
    }
    function play() {
      if (state.frame >= frames() - 1) { setFrame(0); }
      state.playing = true; ui.play.textContent = 'Pause'; ui.play.setAttribute('aria-pressed', 'true');
      var tick = 40;
      state.timer = setInterval(function () {
        // 1× plays the run in 15 s; the speeds multiply that.
        var end = times[frames() - 1], rate = Math.max(end - times[0], 1e-9) / 15 * Number(ui.speed.value);
        state.t = Math.min(end, state.t + rate * tick / 1000);
        setFrame(frameAt(state.t));
        state.t = Math.max(state.t, times[state.frame]);
        if (state.t >= end) { stop(); }
      }, tick);
    }
    function reset() { bounds(); ui.time.max = String(Math.max(0, frames() - 1)); setFrame(Math.min(state.frame, frames() - 1)); }

    ui.play.addEventListener('click', function () { if (state.playing) { stop(); } else { play(); } });
    ui.time.addEventListener('input', function () { setFrame(Number(ui.time.value)); });
    ui.est.addEventListener('change', function () { state.est = Number(ui.est.value); fillRuns(); reset(); });
    ui.run.addEventListener('change', function () { state.run = Number(ui.run.value); reset(); });
    ui.view.addEventListener('change', function () { state.axes = ui.view.value.split(',').map(Number); reset(); });
    ui.scale.addEventListener('change', function () { state.scale = Number(ui.scale.value); draw(); });
    root.addEventListener('keydown', function (ev) {
      // Buttons, selectors and the slider keep their own keys.
      if (['SELECT', 'INPUT', 'BUTTON', 'A'].indexOf(ev.target.tagName) >= 0) { return; }
      var k = ev.key;
      if (k === ' ') { ui.play.click(); } else if (k === 'ArrowRight') { stop(); setFrame(state.frame + 1); }
      else if (k === 'ArrowLeft') { stop(); setFrame(state.frame - 1); } else if (k === 'Home') { stop(); setFrame(0); }
      else if (k === 'End') { stop(); setFrame(frames() - 1); } else { return; }
      ev.preventDefault();
    });

    // #t=12.5&run=2&est=rkf: the moment a link points at.
    function fromHash() {
      var q = {};
      location.hash.replace(/^#/, '').split('&').forEach(function (kv) {
        var p = kv.split('='); if (p[0]) { q[p[0]] = decodeURIComponent(p[1] || ''); }
      });
      if (q.est !== undefined) {
        data.estimators.forEach(function (e, i) { if (e.label === q.est) { state.est = i; } });
        ui.est.value = String(state.est);
      }
      fillRuns();
      if (q.run !== undefined) {
        current(); data.estimators[state.est].runs.forEach(function (r, i) { if (String(r.run) === q.run) { state.run = i; } });
        ui.run.value = String(state.run);
      }
      if (D === 3 && q.view !== undefined && /^[0-2],[0-2]$/.test(q.view)) {
        ui.view.value = q.view; state.axes = ui.view.value.split(',').map(Number);
      }
      bounds(); ui.time.max = String(Math.max(0, frames() - 1));
      setFrame(q.t !== undefined ? frameAt(Number(q.t)) : 0);
      if (q.t !== undefined) {
        // After the figures above have their size, so that the player stays in view.
        if (document.readyState === 'complete') { root.scrollIntoView(); }
        else { window.addEventListener('load', function () { root.scrollIntoView(); }); }
      }
      return q;
    }
    var query = fromHash();
    window.addEventListener('hashchange', function () { stop(); fromHash(); });

    // With `selftest` in the link (the browser test): two frames must differ, and Play must move on.
    if (query.selftest !== undefined) {
      var sig = function () {
        var s = canvas.toDataURL('image/png'), h = 0;
        for (var i = 0; i < s.length; i++) { h = (h * 31 + s.charCodeAt(i)) | 0; }
        return h;
      };
      var keep = state.frame;
      setFrame(0); var first = sig();
      setFrame(frames() - 1); var last = sig();
      setFrame(keep);
      ui.status.setAttribute('data-frames-differ', String(first !== last));
      // How much of the canvas is drawn (not white) at the linked moment.
      var px = ctx.getImageData(0, 0, canvas.width, canvas.height).data, ink = 0;
      for (var q = 0; q < px.length; q += 4) { if (px[q] < 250 || px[q + 1] < 250 || px[q + 2] < 250) { ink++; } }
      ui.status.setAttribute('data-ink', (ink / (px.length / 4)).toFixed(4));
      ui.status.setAttribute('data-hash-frame', String(keep));
      setFrame(0); ui.play.click();
      setTimeout(function () {
        ui.status.setAttribute('data-play-advanced', String(state.frame > 0));
        ui.status.setAttribute('data-playing', String(state.playing));
        ui.play.click();
        ui.status.setAttribute('data-paused', String(!state.playing));
        // The selectors and the slider, as a user's input events drive them.
        var before = root.getAttribute('data-estimator');
        ui.est.value = String((state.est + 1) % data.estimators.length);
        ui.est.dispatchEvent(new Event('change'));
        var estOk = data.estimators.length < 2 || root.getAttribute('data-estimator') !== before;
        ui.time.value = '1';
        ui.time.dispatchEvent(new Event('input'));
        var sliderOk = frames() < 2 || root.getAttribute('data-frame') === '1';
        ui.status.setAttribute('data-controls', String(estOk && sliderOk));
        fromHash();
      }, 2000);
    }
  }
})();
