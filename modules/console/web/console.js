// The mosaicloc console: the map's mosaic from its tiles, report layers and the live vehicle.
// World frame in millimetres: Leaflet's "lat" is y, "lng" is x. Zoom 0 shows map level 0 at
// one screen pixel per map pixel; zoom -k shows level k.
'use strict';

(function () {
  const token = new URLSearchParams(location.search).get('token');
  const withToken = (url) =>
    token ? url + (url.includes('?') ? '&' : '?') + 'token=' + encodeURIComponent(token) : url;
  const $ = (id) => document.getElementById(id);
  const fail = (message) => { $('error').textContent += message + '\n'; };

  async function api(path) {
    const response = await fetch(withToken(path));
    if (!response.ok) throw new Error(path + ': HTTP ' + response.status);
    return response.json();
  }

  const LOCK_NAMES = {0: 'dead reckoning', 1: 'tracking', 2: 'degraded', 3: 'lost', 4: 'off-map', 5: 'searching'};
  const LOCK_COLOURS = {0: '#888888', 1: '#1a9641', 2: '#f0a020', 3: '#d7191c', 4: '#9e9e9e', 5: '#2b83ba'};
  const latLng = (x, y) => [y, x];

  // Fix quality 0.5 (red) .. 1 (green); frames without a fix grey.
  function qualityColour(point) {
    if (!point[3]) return '#9e9e9e';
    const t = Math.max(0, Math.min(1, (point[4] / 1000 - 0.5) / 0.5));
    const mix = (a, b) => Math.round(a * (1 - t) + b * t);
    return `rgb(${mix(215, 26)},${mix(25, 150)},${mix(28, 65)})`;
  }
  const stateColour = (point) => LOCK_COLOURS[point[2]] || '#000000';
  // The localizer's modes (design.md section 7c), as the report's map_mode.png draws them.
  const MODE_COLOURS = {'track': '#28aa3c', 'visual-odometry': '#146ec8', 'dead-reckoning': '#f08c14',
                        'searching': '#c828c8'};
  const seamColour = (point) => (point[2] < 0.05 ? '#1a9641' : point[2] < 0.2 ? '#f0a020' : '#d7191c');

  // A path as polylines, one per run of points of one colour (each run ends on the next
  // run's first point, so the path has no gaps).
  function colouredPath(points, colourOf, className) {
    const group = L.featureGroup();
    let run = [];
    let colour = null;
    for (const point of points) {
      const c = colourOf(point);
      const ll = latLng(point[0], point[1]);
      if (c !== colour && run.length) {
        run.push(ll);
        group.addLayer(L.polyline(run, {color: colour, weight: 3, className, interactive: false}));
        run = [];
      }
      colour = c;
      run.push(ll);
    }
    if (run.length) group.addLayer(L.polyline(run, {color: colour, weight: 3, className, interactive: false}));
    return group;
  }

  // A layer whose features are made when it is first shown: a large map's tiles and cells would
  // otherwise delay the first view.
  function lazyGroup(make) {
    const group = L.featureGroup();
    group.once('add', () => make().forEach((layer) => group.addLayer(layer)));
    return group;
  }

  function legend(entries) {
    return entries.map(([colour, text]) => `<i style="background:${colour}"></i>${text}`).join('<br>');
  }

  // A scale bar in millimetres or metres (Leaflet's own assumes geographic metres).
  const ScaleBar = L.Control.extend({
    options: {position: 'bottomleft', maxWidth: 150},
    onAdd(map) {
      this._div = L.DomUtil.create('div', 'scale-bar');
      map.on('zoomend', this._update, this);
      this._update();
      return this._div;
    },
    _update() {
      const mmPerPx = this._mmPerPx / Math.pow(2, this._map.getZoom());
      const most = mmPerPx * this.options.maxWidth;
      const power = Math.pow(10, Math.floor(Math.log10(most)));
      const nice = [5, 2, 1].map((m) => m * power).find((v) => v <= most) || power;
      this._div.style.width = Math.round(nice / mmPerPx) + 'px';
      this._div.textContent = nice >= 1000 ? nice / 1000 + ' m' : nice + ' mm';
    },
  });

  async function main() {
    const info = await api('/api/map');
    const r = info.mm_per_px;
    const x0 = info.origin_x_mm;
    const y0 = info.origin_y_mm;
    const tileSize = info.tile_size_px;
    const top = info.levels.length - 1;
    $('map-file').textContent = info.file;
    $('map-resolution').textContent = r + ' mm/px, ' + info.levels.length + ' levels';
    $('map-tiles').textContent = info.levels.map((l) => l.tiles).join(' / ');
    $('map-places').textContent = info.place_index
      ? info.place_index.cells + ' cells, ' + (info.place_index.bytes / 1048576).toFixed(1) + ' MiB'
      : 'none (mosaicloc map index)';

    const crs = L.extend({}, L.CRS.Simple, {transformation: new L.Transformation(1 / r, -x0 / r, -1 / r, y0 / r)});
    const map = L.map('map', {crs, minZoom: -top - 2, maxZoom: 4, zoomSnap: 1, attributionControl: false});
    const b = info.bounds_mm || [-1000, -1000, 1000, 1000];
    const bounds = L.latLngBounds([latLng(b[0], b[1]), latLng(b[2], b[3])]);
    // The map's version is in every tile's address: when the map is written (a live run's
    // automatic mapping and map updates, a revert), the page asks for the tiles anew.
    let mapVersion = info.map_version;
    const MapTiles = L.TileLayer.extend({
      getTileUrl: (coords) => withToken(`/api/tiles/${-coords.z}/${coords.x}/${coords.y}.png?v=${mapVersion}`),
    });
    let tilesLoaded = 0;
    const tiles = new MapTiles('', {
      tileSize, minNativeZoom: -top, maxNativeZoom: 0, minZoom: -top - 2, maxZoom: 4, bounds, noWrap: true,
    });
    tiles.on('tileload', () => {
      tilesLoaded += 1;
      $('tiles-loaded').textContent = tilesLoaded;
      document.body.dataset.tilesLoaded = tilesLoaded;
    });
    tiles.addTo(map);
    // A view to share: #X,Y,ZOOM (mm, mm, zoom level) in the address; else the whole map.
    const view = location.hash.slice(1).split(',').map(Number);
    if (view.length === 3 && view.every(Number.isFinite)) map.setView(latLng(view[0], view[1]), view[2]);
    else map.fitBounds(bounds);
    map.on('moveend', () => {
      const c = map.getCenter();
      history.replaceState(null, '', `${location.search}#${c.lng.toFixed(1)},${c.lat.toFixed(1)},${map.getZoom()}`);
    });
    const scaleBar = new ScaleBar();
    scaleBar._mmPerPx = r;
    scaleBar.addTo(map);

    // The world frame's axes at the origin: x red, y green.
    const axisMm = Math.max(50, Math.pow(10, Math.round(Math.log10((b[2] - b[0]) / 10))));
    const axes = L.featureGroup([
      L.polyline([latLng(0, 0), latLng(axisMm, 0)], {color: '#e41a1c', weight: 3, className: 'axis-x'}),
      L.polyline([latLng(0, 0), latLng(0, axisMm)], {color: '#4daf4a', weight: 3, className: 'axis-y'}),
    ]).bindTooltip('world origin; x red, y green, ' + axisMm + ' mm');
    axes.addTo(map);

    // The mapped tiles of a coarse level: where the lanes were mapped.
    const laneTileMm = tileSize * r * Math.pow(2, info.mapped_tiles.level);
    const lanes = lazyGroup(() => info.mapped_tiles.tiles.map(([col, row]) => L.rectangle(
      [latLng(x0 + col * laneTileMm, y0 - (row + 1) * laneTileMm), latLng(x0 + (col + 1) * laneTileMm, y0 - row * laneTileMm)],
      {color: '#00bcd4', weight: 1, fillOpacity: 0.05, interactive: false, className: 'mapped-tile'})));

    const overlays = {'world axes': axes, 'mapped tiles': lanes};
    // The map's quality layer: each cell of the floor by what a fix there can expect.
    const quality = await api('/api/quality');
    if (quality.available) {
      const VERDICTS = {0: ['#1a9641', 'good'], 1: ['#f0a020', 'little texture'], 2: ['#d7191c', 'repeats nearby'],
        3: ['#2b83ba', 'lane edge, not judged in full']};
      const cellMm = quality.cell_mm;
      const renderer = L.canvas({padding: 0.5});
      const weak = quality.cells.filter((c) => c[5] === 1 || c[5] === 2).length;
      overlays['map quality'] = lazyGroup(() => quality.cells.filter((c) => c[5] >= 0).map(
        ([col, row, mapped, texture, ambiguity, verdict]) => L.rectangle(
          [latLng(x0 + col * cellMm, y0 - (row + 1) * cellMm), latLng(x0 + (col + 1) * cellMm, y0 - row * cellMm)],
          {renderer, color: VERDICTS[verdict][0], weight: 0, fillOpacity: 0.45})
          .bindTooltip(`${VERDICTS[verdict][1]}: texture ${texture}, best match elsewhere ${ambiguity}, ` +
                       `mapped ${Math.round(mapped * 100)} %`)));
      $('map-quality').textContent = `${quality.cells.length} cells of ${cellMm} mm, ${weak} weak`;
      document.body.dataset.qualityCells = quality.cells.length;
    } else {
      $('map-quality').textContent = 'none (mosaicloc map quality MAP --out DIR)';
    }
    // The map's history (design.md section 4): the level-0 tiles each recorded write replaced
    // or added, blue for automatic mapping, orange for map updates, grey dashed once reverted.
    const tileMm = tileSize * r;
    const historyLayer = L.featureGroup();
    function showHistory(history) {
      historyLayer.clearLayers();
      for (const u of history.updates) {
        const kind = u.reverted ? 'reverted' : u.kind;
        const style = {mapping: ['#2b83ba', null], update: ['#e66101', null], other: ['#7b3294', null],
                       reverted: ['#9e9e9e', '4 4']}[kind];
        const text = `#${u.id} ${u.time}: ${u.reason}` + (u.reverted ? ` (reverted ${u.reverted})` : '');
        for (const [col, row] of u.cells) {
          historyLayer.addLayer(L.rectangle(
            [latLng(x0 + col * tileMm, y0 - (row + 1) * tileMm), latLng(x0 + (col + 1) * tileMm, y0 - row * tileMm)],
            {color: style[0], dashArray: style[1], weight: 1, fillOpacity: 0.15, className: 'history-tile history-' + kind})
            .bindTooltip(text));
        }
      }
      const last = history.updates[history.updates.length - 1];
      $('map-history').textContent = history.count
        ? `${history.count} update${history.count === 1 ? '' : 's'}, ${history.in_force} in force; ` +
          `last #${last.id} ${last.time}` : 'none';
      document.body.dataset.historyUpdates = history.count;
      document.body.dataset.historyTiles = historyLayer.getLayers().length;
    }
    overlays['map history'] = historyLayer;
    // Not waited for: the live vehicle must not wait behind it.
    api('/api/history').then((history) => {
      showHistory(history);
      if (history.count > 0) historyLayer.addTo(map);
    }).catch((error) => fail(String(error)));
    // A map written while the page is open: new tiles, layout and history. A live run's stream
    // says when (its map_version); without one the page asks every 2 s.
    async function refreshMap(version) {
      if (version === undefined || version === mapVersion) return;
      mapVersion = version;
      document.body.dataset.mapVersion = mapVersion;
      tiles.redraw();
      const now = await api('/api/history');
      showHistory(now);
      if (now.count > 0 && !map.hasLayer(historyLayer)) historyLayer.addTo(map);
      const fresh = await api('/api/map');
      $('map-tiles').textContent = fresh.levels.map((l) => l.tiles).join(' / ');
    }
    if (!info.live_run) {
      setInterval(() => api('/api/history').then((now) => refreshMap(now.map_version)).catch((error) => fail(String(error))),
                  2000);
    }
    document.body.dataset.mapVersion = mapVersion;

    const layerControl = L.control.layers(null, overlays, {collapsed: false}).addTo(map);
    const legendControl = L.control({position: 'bottomright'});
    legendControl.onAdd = () => {
      const div = L.DomUtil.create('div', 'legend');
      div.innerHTML = legend(Object.keys(LOCK_NAMES).map((k) => [LOCK_COLOURS[k], LOCK_NAMES[k]]));
      return div;
    };
    legendControl.addTo(map);

    await loadReports(map, layerControl);
    if (info.live_run) startLive(map, layerControl, r, refreshMap);
    else $('live-link').textContent = 'no live run (mosaicloc run with console.enabled shows one)';
    document.body.dataset.ready = 'yes';
  }

  async function loadReports(map, layerControl) {
    const reports = await api('/api/reports');
    let first = true;
    for (const entry of reports) {
      const report = await api('/api/reports/' + entry.id);
      const item = document.createElement('li');
      const m = report.metrics || {};
      const figure = (key, digits, unit) => (m[key] === null || m[key] === undefined ? '–' : Number(m[key]).toFixed(digits) + unit);
      if (report.kind === 'replay') {
        const byState = colouredPath(report.points, stateColour, 'report-path report-state');
        const byQuality = colouredPath(report.points, qualityColour, 'report-path report-quality');
        layerControl.addOverlay(byState, report.name + ': lock state');
        layerControl.addOverlay(byQuality, report.name + ': fix quality');
        if (report.columns.includes('error_mm')) {
          // Against the ground truth (a simulated or surveyed drive): green within 0.05 mm, amber
          // within 1 mm, red beyond (a wrong fix, when the frame had one).
          const byError = colouredPath(report.points, (p) => (p[6] === null ? '#9e9e9e' : p[6] <= 0.05 ? '#1a9641'
            : p[6] <= 1.0 ? '#f0a020' : '#d7191c'), 'report-path report-error');
          layerControl.addOverlay(byError, report.name + ': error against the truth');
        }
        const modeAt = report.columns.indexOf('mode');
        if (modeAt >= 0) {
          const byMode = colouredPath(report.points, (p) => MODE_COLOURS[p[modeAt]] || '#9e9e9e',
                                      'report-path report-mode');
          layerControl.addOverlay(byMode, report.name + ': mode');
        }
        if (first) byState.addTo(map);  // the first replay's; the others are a click away
        first = false;
        item.textContent = `${report.name} (replay): ${report.frames} frames, ${report.fixes} fixes, ` +
          `wrong fixes ${m.wrong_fixes === null || m.wrong_fixes === undefined ? 'n/a' : m.wrong_fixes}, ` +
          `RMS ${figure('position_rms_mm', 4, ' mm')}, repeatability ${figure('revisit_repeatability_mm', 4, ' mm')}`;
      } else {
        const seams = colouredPath(report.points, seamColour, 'report-path report-seams');
        for (const loop of report.loops) {
          seams.addLayer(L.polyline([latLng(...loop.from), latLng(...loop.to)], {
            color: loop.accepted ? '#2b83ba' : '#d7191c', weight: loop.accepted ? 2 : 1,
            dashArray: loop.accepted ? null : '4 4', className: loop.accepted ? 'loop-accepted' : 'loop-rejected',
          }).bindTooltip(loop.accepted ? 'loop closed, ' + loop.correction_mm.toFixed(2) + ' mm' : 'loop refused: ' + loop.reason));
        }
        layerControl.addOverlay(seams, report.name + ': seams and loops');
        seams.addTo(map);
        item.textContent = `${report.name} (mapping): ${report.frames} frames, ` +
          `${report.loops.filter((l) => l.accepted).length} loops closed of ${report.loops.length}`;
      }
      $('reports').appendChild(item);
    }
    document.body.dataset.reports = reports.length;
  }

  function startLive(map, layerControl, mmPerPx, refreshMap) {
    const live = L.featureGroup();
    const path = L.polyline([], {color: '#ffffff', weight: 2, opacity: 0.8, className: 'live-path', interactive: false});
    const ellipse = L.polygon([], {color: '#ff00ff', weight: 1, fillOpacity: 0.2, className: 'live-ellipse'});
    const marker = L.circleMarker([0, 0], {radius: 6, color: '#ff00ff', weight: 2, fillOpacity: 0.9, className: 'live-pose'});
    const heading = L.polyline([], {color: '#ff00ff', weight: 2, className: 'live-heading'});
    let shown = false;
    let updates = 0;

    function show(state) {
      const status = state.status || {};
      if (status.plc !== undefined) {
        $('live-plc').textContent = `${status.plc}, ${status.plc_round_trip_ms ?? '–'} ms, errors ${status.plc_errors ?? 0}, ` +
          `requests ${status.requests ?? 0}/${status.answered ?? 0}` + (status.heartbeat ? ', heartbeat ' + status.heartbeat : '');
        $('live-fps').textContent = status.frames_per_s ?? '–';
        $('live-fix-rate').textContent = status.frames_per_s ? (100 * status.fixes_per_s / status.frames_per_s).toFixed(1) + ' %' : '–';
        $('live-latency').textContent = (status.latency_p50_ms ?? '–') + ' ms p50';
      }
      if (state.map_version !== undefined) refreshMap(state.map_version).catch((error) => fail(String(error)));
      if (!state.live) return;
      updates += 1;
      document.body.dataset.liveUpdates = updates;
      $('live-updates').textContent = updates;
      $('live-link').textContent = 'live, t ' + state.t_s.toFixed(1) + ' s, ' + state.frames + ' frames';
      const lock = $('live-lock');
      lock.textContent = LOCK_NAMES[state.lock] || String(state.lock);
      lock.className = 'lock-' + state.lock;
      $('live-mode').textContent = state.mode || '–';
      if (state.height_mm) $('live-height').textContent = state.height_mm.toFixed(2) + ' mm (scale ' + state.scale.toFixed(4) + ')';
      if (!state.known) {
        $('live-pose').textContent = 'unknown';
        return;
      }
      const [cxx, cxy, cyy] = state.covariance_mm2;
      $('live-pose').textContent = `${state.x_mm.toFixed(2)}, ${state.y_mm.toFixed(2)} mm, ${(state.yaw_rad * 180 / Math.PI).toFixed(2)}°`;
      $('live-sigma').textContent = Math.sqrt(Math.max(0, cxx + cyy)).toFixed(3) + ' mm, ' +
        (state.sigma_yaw_rad * 180 / Math.PI).toFixed(3) + '°';
      const here = latLng(state.x_mm, state.y_mm);
      marker.setLatLng(here);
      marker.setStyle({color: LOCK_COLOURS[state.lock] || '#ff00ff'});
      const arm = 40 * mmPerPx / Math.pow(2, Math.min(0, map.getZoom()));  // 40 screen px
      heading.setLatLngs([here, latLng(state.x_mm + arm * Math.cos(state.yaw_rad), state.y_mm + arm * Math.sin(state.yaw_rad))]);
      // The 3-sigma ellipse of the position covariance.
      const trace = cxx + cyy;
      const root = Math.sqrt(Math.max(0, (cxx - cyy) * (cxx - cyy) / 4 + cxy * cxy));
      const l1 = Math.max(0, trace / 2 + root);
      const l2 = Math.max(0, trace / 2 - root);
      const angle = 0.5 * Math.atan2(2 * cxy, cxx - cyy);
      const ring = [];
      for (let k = 0; k < 36; ++k) {
        const t = (k / 36) * 2 * Math.PI;
        const u = 3 * Math.sqrt(l1) * Math.cos(t);
        const v = 3 * Math.sqrt(l2) * Math.sin(t);
        ring.push(latLng(state.x_mm + u * Math.cos(angle) - v * Math.sin(angle), state.y_mm + u * Math.sin(angle) + v * Math.cos(angle)));
      }
      ellipse.setLatLngs(ring);
      if (state.path) path.setLatLngs(state.path.map(([x, y]) => latLng(x, y)));
      else path.addLatLng(here);
      if (!shown) {
        shown = true;
        live.addLayer(path).addLayer(ellipse).addLayer(heading).addLayer(marker);
        live.addTo(map);
        layerControl.addOverlay(live, 'vehicle (live)');
      }
    }
    api('/api/live').then((state) => {
      show(state);
      // ?follow=N: follow N updates, then keep the page as it is (a snapshot, or a page that
      // should not hold a stream open); else follow until the page closes.
      const follow = Number(new URLSearchParams(location.search).get('follow') || 0);
      const stream = new EventSource(withToken('/api/live/stream'));
      let received = 0;
      stream.onmessage = (event) => {
        show(JSON.parse(event.data));
        received += 1;
        if (follow > 0 && received >= follow) stream.close();
      };
    }).catch((error) => fail(String(error)));
  }

  main().catch((error) => fail(String(error)));
})();
