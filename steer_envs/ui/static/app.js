// steer-ui page: draws the env's view, sends the domain's interactions (sketches, points, nudges, pushes) over a
// WebSocket and draws what comes back (steered plans, a controller's overlays). The controls are built from the
// domain's declaration in the server's `ready` message. State for tests and the benchmark: window.steerUI.
"use strict";

const COLORS = { sketch: "#c81ec8", plan: "#149f9f", collide: "#f08c1e", chosen: "#1b2a8f", agent: "#dc1e1e" };
const MAX_DISPLAY = 760; // CSS pixels of the longest image side
const HISTORY = 200; // round trips kept in window.steerUI.history

const ui = {
  ready: false, connected: false, width: 0, height: 0, scale: 1, settings: {}, playing: false, declaration: null,
  plans: [], chosen: -1, collides: null, interaction: [], interactionKind: "none", overlays: {}, drawn: {}, panel: [],
  agent: null, lastInteraction: null, history: [], errors: [], plansReceived: 0, drawnPlans: 0, frames: 0, done: false,
  steps: null, notices: [], downloads: [],
};
window.steerUI = ui;
window.addEventListener("error", (event) => ui.errors.push(`page error: ${event.message}`));
window.addEventListener("unhandledrejection", (event) => ui.errors.push(`page error: ${event.reason}`));

const $ = (id) => document.getElementById(id);
const frame = $("frame");
const overlay = $("overlay");
const ctx = overlay.getContext("2d");
const images = {}; // overlay name -> {src, img} of image overlays
let socket = null;
let sentAt = null; // performance.now() of the latest steer request
let drag = null; // {interaction, points} of the gesture in progress (image pixels)

// ------------------------------------------------------------------ socket
function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${scheme}://${location.host}/ws`);
  socket.onopen = () => { ui.connected = true; badge("connected", "ok"); send({ type: "hello" }); };
  socket.onclose = () => { ui.connected = false; ui.ready = false; badge("disconnected — reload to reconnect", "bad"); };
  socket.onerror = () => badge("connection error", "bad");
  socket.onmessage = (event) => {
    let msg;
    try { msg = JSON.parse(event.data); } catch (err) { showError(`bad reply from the server: ${err}`); return; }
    const handler = HANDLERS[msg.type];
    if (handler) handler(msg); else showError(`unknown reply type ${msg.type}`);
  };
}

function send(msg) {
  if (!socket || socket.readyState !== WebSocket.OPEN) { showError("not connected"); return false; }
  socket.send(JSON.stringify(msg));
  return true;
}

function badge(text, cls) { const b = $("connection"); b.textContent = text; b.className = `badge ${cls}`; }

function showError(message) {
  ui.errors.push(message);
  const box = $("error");
  box.textContent = message;
  box.hidden = false;
  clearTimeout(showError.timer);
  showError.timer = setTimeout(() => { box.hidden = true; }, 8000);
}

// a message about the request that is not an error (e.g. a push the arm refused: nothing moved)
function showNotice(message) {
  const box = $("notice");
  box.textContent = message;
  box.hidden = !message;
  if (message) ui.notices.push(message);
}

function el(tag, props = {}, children = []) {
  const node = Object.assign(document.createElement(tag), props);
  for (const child of children) node.append(child);
  return node;
}

// ------------------------------------------------------ controls from the declaration
function buildControls(msg) {
  const decl = msg.declaration;
  ui.declaration = decl;
  $("env-name").textContent = `${decl.title} · ${msg.env} · ${msg.policy}`;
  const modes = $("modes");
  modes.replaceChildren();
  decl.interactions.forEach((it, i) => {
    const input = el("input", { type: "radio", name: "mode", value: it.kind, checked: i === 0 });
    input.addEventListener("change", () => { $("hint").textContent = it.hint; });
    modes.append(el("label", {}, [input, ` ${it.label}`]));
  });
  $("hint").textContent = decl.interactions.length ? decl.interactions[0].hint : "This domain takes no input.";
  $("sampler-box").hidden = !decl.steering;
  for (const row of document.querySelectorAll(".steer-only")) row.hidden = !decl.steering;
  $("execute-label").firstChild.textContent = decl.steering ? "Waypoints per step " : "Env steps per Step ";
  const legend = $("legend");
  legend.replaceChildren();
  const row = (label, color, cls = "") => {
    const swatch = el("span", { className: `swatch ${cls}` });
    swatch.style.background = color;
    legend.append(el("li", {}, [swatch, label]));
  };
  for (const ov of decl.overlays) {
    if (ov.kind === "plans") {
      row("your sketch / point", COLORS.sketch, "thick");
      row("sampled plan", COLORS.plan);
      if (msg.collisions) row("plan through a wall", COLORS.collide);
      row("chosen plan (executed by Step)", COLORS.chosen, "thick");
    }
    for (const [label, color] of ov.legend) row(label, color, ov.kind === "markers" ? "dot" : "");
  }
  const dragger = decl.interactions.find((it) => it.gesture === "drag-agent");
  row(dragger ? `agent (drag it in ${dragger.label} mode)` : "agent", COLORS.agent, "dot");
}

// ---------------------------------------------------------------- handlers
const HANDLERS = {
  ready(msg) {
    ui.width = msg.width; ui.height = msg.height;
    ui.scale = Math.min(4, MAX_DISPLAY / Math.max(msg.width, msg.height));
    frame.width = Math.round(msg.width * ui.scale); frame.height = Math.round(msg.height * ui.scale);
    overlay.width = frame.width; overlay.height = frame.height;
    buildControls(msg);
    const select = $("sampler");
    select.innerHTML = "";
    for (const name of msg.samplers) {
      const opt = document.createElement("option");
      opt.value = name; opt.textContent = name;
      if (!msg.diffusion && ["BI", "GD", "SS"].includes(name)) opt.disabled = true;
      select.appendChild(opt);
    }
    $("batch").max = msg.max_batch;
    applySettings(msg.settings);
    HANDLERS.frame(msg);
    ui.ready = true;
  },
  settings(msg) {
    applySettings(msg.settings);
    if (ui.declaration && ui.declaration.steering && ui.lastInteraction) {
      steer(ui.lastInteraction.kind, ui.lastInteraction.points); // show the new sampler's plans
    }
  },
  plans(msg) {
    const t0 = performance.now();
    ui.plans = msg.plans; ui.chosen = msg.chosen; ui.collides = msg.collides;
    ui.interaction = msg.interaction; ui.interactionKind = msg.kind;
    ui.plansReceived += 1;
    if (msg.panel) showPanel(msg.panel);
    draw();
    const drawMs = performance.now() - t0;
    const roundTrip = sentAt === null ? null : performance.now() - sentAt;
    sentAt = null;
    const entry = { id: msg.id, sampler: msg.sampler, batch: msg.plans.length, draw_ms: drawMs, roundtrip_ms: roundTrip, ...msg.timings };
    ui.history.push(entry);
    if (ui.history.length > HISTORY) ui.history.shift();
    stats(msg, entry);
  },
  frame(msg) {
    const t0 = performance.now();
    frame.src = msg.image;
    ui.frames += 1;
    ui.agent = msg.agent;
    ui.done = msg.done;
    ui.steps = msg.steps;
    if (msg.why !== "ready") { ui.plans = []; ui.chosen = -1; ui.collides = null; }
    if (msg.why === "reset") { ui.interaction = []; ui.lastInteraction = null; $("error").hidden = true; }
    if (msg.why === "ready" || msg.why === "reset") ui.overlays = {};
    Object.assign(ui.overlays, msg.overlays || {});
    showPanel(msg.panel || []);
    showNotice(msg.notice || "");
    $("seed").value = msg.seed;
    const state = msg.done ? "ended — press Reset" : "running";
    const extra = [msg.mode && `mode ${msg.mode}`, msg.success && "success", msg.violation && "constraint violated",
      msg.steps !== null && msg.steps !== undefined && `${msg.steps} steps`].filter(Boolean);
    $("s-episode").textContent = [state, ...extra].join(", ");
    draw();
    if (msg.timings && sentAt !== null) { // the answer to a push or nudge: its round trip, as for plans
      const now = performance.now();
      ui.history.push({ kind: msg.why, draw_ms: now - t0, roundtrip_ms: now - sentAt, ...msg.timings });
      if (ui.history.length > HISTORY) ui.history.shift();
      sentAt = null;
    }
  },
  download(msg) {
    const bytes = Uint8Array.from(atob(msg.data), (c) => c.charCodeAt(0));
    const url = URL.createObjectURL(new Blob([bytes], { type: msg.mime }));
    const link = el("a", { href: url, download: msg.name });
    document.body.append(link); link.click(); link.remove();
    setTimeout(() => URL.revokeObjectURL(url), 60000);
    ui.downloads.push({ name: msg.name, mime: msg.mime, size: bytes.length, identical: msg.identical });
    $("export").disabled = false;
    if (msg.identical === false) showNotice("the replayed frames differ from the session's (another backend?)");
  },
  playing(msg) { ui.playing = msg.playing; $("play").textContent = msg.playing ? "Pause" : "Play"; },
  error(msg) { sentAt = null; $("export").disabled = false; showError(msg.message); },
};

function applySettings(settings) {
  ui.settings = settings;
  if ("sampler" in settings) {
    $("sampler").value = settings.sampler;
    $("batch").value = settings.batch;
    $("guide_ratio").value = settings.guide_ratio ?? "";
    $("mcmc_steps").value = settings.mcmc_steps ?? "";
  }
  $("execute").value = settings.execute ?? "";
}

function showPanel(rows) {
  ui.panel = rows;
  const table = $("panel");
  table.replaceChildren(...rows.map(([label, value]) => el("tr", {}, [el("th", { textContent: label }), el("td", { textContent: value })])));
  table.hidden = rows.length === 0;
}

function stats(msg, entry) {
  const costs = msg.costs.filter((c) => c !== null);
  const chosen = msg.costs[msg.chosen];
  $("s-sampler").textContent = `${msg.sampler} · ${msg.plans.length} plans · ${msg.kind}`;
  $("s-cost").textContent = costs.length
    ? `${chosen.toFixed(3)} / ${(costs.reduce((a, b) => a + b, 0) / costs.length).toFixed(3)}` : "– (unsteered)";
  $("s-collision").textContent = msg.collides
    ? `${msg.collides.filter(Boolean).length} of ${msg.collides.length}` : "–";
  $("s-net").textContent = `${msg.timings.network_ms.toFixed(0)} / ${msg.timings.sampler_ms.toFixed(0)}`;
  $("s-rtt").textContent = `${entry.roundtrip_ms === null ? "–" : entry.roundtrip_ms.toFixed(0)} / ${entry.draw_ms.toFixed(1)}`;
}

// ----------------------------------------------------------------- drawing
function polyline(points, color, width) {
  if (!points.length) return;
  ctx.strokeStyle = color; ctx.lineWidth = width; ctx.lineJoin = "round"; ctx.lineCap = "round";
  ctx.beginPath();
  ctx.moveTo(points[0][0] * ui.scale, points[0][1] * ui.scale);
  for (let i = 1; i < points.length; i++) ctx.lineTo(points[i][0] * ui.scale, points[i][1] * ui.scale);
  ctx.stroke();
}

function dot(p, color, radius) {
  ctx.fillStyle = color;
  ctx.beginPath(); ctx.arc(p[0] * ui.scale, p[1] * ui.scale, radius, 0, 2 * Math.PI); ctx.fill();
}

function arrow(u, v, du, dv, color) {
  const len = Math.hypot(du, dv) * ui.scale;
  if (len < 0.5) { dot([u, v], color, 1.5); return; }
  polyline([[u, v], [u + du, v + dv]], color, 1.5);
  const a = Math.atan2(dv, du), head = Math.min(6, 0.4 * len), x = (u + du) * ui.scale, y = (v + dv) * ui.scale;
  ctx.fillStyle = color;
  ctx.beginPath(); ctx.moveTo(x, y);
  ctx.lineTo(x - head * Math.cos(a - 0.45), y - head * Math.sin(a - 0.45));
  ctx.lineTo(x - head * Math.cos(a + 0.45), y - head * Math.sin(a + 0.45));
  ctx.closePath(); ctx.fill();
}

function overlayColor(ov) { return ov.legend.length ? ov.legend[0][1] : COLORS.plan; }

// overlay kind -> how it is drawn; returns how many things it drew (window.steerUI.drawn, for tests)
const DRAWERS = {
  plans() {
    ctx.globalAlpha = 0.75;
    ui.plans.forEach((plan, i) => {
      if (i !== ui.chosen) polyline(plan, ui.collides && ui.collides[i] ? COLORS.collide : COLORS.plan, 1.5);
    });
    ctx.globalAlpha = 1;
    if (ui.chosen >= 0 && ui.plans[ui.chosen]) polyline(ui.plans[ui.chosen], COLORS.chosen, 3.5);
    ui.drawnPlans = ui.plans.length;
    const shown = drag && drag.interaction.gesture === "path" ? drag.points : ui.interaction;
    if (shown.length === 1) {
      dot(shown[0], COLORS.sketch, 7);
    } else if (shown.length > 1) {
      polyline(shown, COLORS.sketch, 4);
      dot(shown[0], COLORS.sketch, 5);
    }
    return ui.plans.length;
  },
  image(ov, data) {
    if (!data) return 0;
    let entry = images[ov.name];
    if (!entry || entry.src !== data.src) {
      entry = images[ov.name] = { src: data.src, img: new Image(), loaded: false };
      entry.img.onload = () => { entry.loaded = true; draw(); };
      entry.img.src = data.src;
    }
    if (!entry.loaded) return 0;
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(entry.img, 0, 0, overlay.width, overlay.height);
    return 1;
  },
  arrows(ov, data) {
    for (const [u, v, du, dv] of data || []) arrow(u, v, du, dv, overlayColor(ov));
    return (data || []).length;
  },
  lines(ov, data) {
    for (const line of data || []) polyline(line, overlayColor(ov), 2.5);
    return (data || []).length;
  },
  markers(ov, data) {
    for (const p of data || []) dot(p, overlayColor(ov), 6);
    return (data || []).length;
  },
  // rows of mode indices along the run, one bar each at the bottom of the view (mode k: the legend's row k)
  strip(ov, data) {
    if (!data) return 0;
    const rows = data.rows, barH = 12, gap = 3, left = 64, width = overlay.width - left - 8;
    const cell = width / Math.max(1, data.steps);
    let y = overlay.height - rows.length * (barH + gap) - 4;
    ctx.fillStyle = "rgba(255, 255, 255, 0.8)";
    ctx.fillRect(0, y - gap, overlay.width, rows.length * (barH + gap) + gap + 4);
    ctx.font = "11px system-ui, sans-serif"; ctx.textBaseline = "middle";
    for (const [label, modes] of rows) {
      ctx.fillStyle = "#222"; ctx.fillText(label, 6, y + barH / 2);
      modes.forEach((k, i) => {
        ctx.fillStyle = ov.legend[k] ? ov.legend[k][1] : "#999";
        ctx.fillRect(left + i * cell, y, Math.max(cell, 1), barH);
      });
      y += barH + gap;
    }
    return rows.length;
  },
};

function draw() {
  ctx.clearRect(0, 0, overlay.width, overlay.height);
  for (const ov of ui.declaration ? ui.declaration.overlays : []) {
    ui.drawn[ov.name] = DRAWERS[ov.kind](ov, ui.overlays[ov.name]);
  }
  if (drag && drag.interaction.gesture === "drag-agent" && ui.agent) {
    const end = drag.points[drag.points.length - 1];
    ctx.setLineDash([6, 4]);
    polyline([ui.agent, end], COLORS.agent, 2);
    ctx.setLineDash([]);
    dot(end, COLORS.agent, 6);
  }
}

// ------------------------------------------------------------------- input
function imagePixel(event) {
  const rect = overlay.getBoundingClientRect();
  const u = ((event.clientX - rect.left) / rect.width) * ui.width;
  const v = ((event.clientY - rect.top) / rect.height) * ui.height;
  return [Math.min(ui.width, Math.max(0, u)), Math.min(ui.height, Math.max(0, v))];
}

function currentInteraction() {
  const checked = document.querySelector("input[name=mode]:checked");
  return checked && ui.declaration ? ui.declaration.interactions.find((it) => it.kind === checked.value) : null;
}

function steer(kind, points) {
  ui.lastInteraction = { kind, points };
  if (send({ type: "steer", kind, points })) sentAt = performance.now();
}

overlay.addEventListener("pointerdown", (event) => {
  const interaction = currentInteraction();
  if (!ui.ready || !interaction) return;
  overlay.setPointerCapture(event.pointerId);
  drag = { interaction, points: [imagePixel(event)] };
  draw();
});
overlay.addEventListener("pointermove", (event) => {
  if (!drag) return;
  const p = imagePixel(event);
  if (drag.interaction.gesture === "path") {
    const last = drag.points[drag.points.length - 1];
    if (Math.hypot(p[0] - last[0], p[1] - last[1]) >= 0.5 && drag.points.length < 4096) drag.points.push(p);
  } else {
    drag.points = [p];
  }
  draw();
});
overlay.addEventListener("pointerup", (event) => {
  if (!drag) return;
  const { interaction, points } = drag;
  const end = imagePixel(event);
  drag = null;
  if (interaction.gesture === "drag-agent") {
    if (send({ type: interaction.message, to: end })) sentAt = performance.now();
  } else if (interaction.gesture === "click" || points.length < 2) {
    steer("point", [end]);
  } else {
    steer("sketch", points);
  }
  draw();
});
overlay.addEventListener("pointercancel", () => { drag = null; draw(); });

function numberOrNull(id) { const v = $(id).value; return v === "" ? null : Number(v); }

function configure(key) {
  const value = key === "sampler" ? $("sampler").value : numberOrNull(key);
  send({ type: "configure", [key]: value });
}
for (const key of ["sampler", "batch", "guide_ratio", "mcmc_steps", "execute"]) $(key).addEventListener("change", () => configure(key));
$("resteer").addEventListener("click", () => {
  if (ui.lastInteraction) steer(ui.lastInteraction.kind, ui.lastInteraction.points); else steer("none", null);
});
$("reset").addEventListener("click", () => send({ type: "reset", seed: Number($("seed").value) || 0 }));
$("step").addEventListener("click", () => send({ type: "step" }));
$("play").addEventListener("click", () => send({ type: ui.playing ? "pause" : "play" }));
$("save").addEventListener("click", () => send({ type: "save" }));
$("export").addEventListener("click", () => { if (send({ type: "export", format: "mp4" })) $("export").disabled = true; });

connect();
