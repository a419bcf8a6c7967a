// steer-ui page: draws the env's view, sends sketches / points / nudges over a WebSocket,
// draws the steered plans that come back. State for tests and the benchmark: window.steerUI.
"use strict";

const COLORS = { sketch: "#c81ec8", plan: "#149f9f", collide: "#f08c1e", chosen: "#1b2a8f", agent: "#dc1e1e" };
const MAX_DISPLAY = 760; // CSS pixels of the longest image side
const HISTORY = 200; // round trips kept in window.steerUI.history

const ui = {
  ready: false, connected: false, width: 0, height: 0, scale: 1, settings: {}, playing: false,
  plans: [], chosen: -1, collides: null, interaction: [], interactionKind: "none",
  agent: null, lastInteraction: null, history: [], errors: [], plansReceived: 0, drawnPlans: 0, frames: 0,
};
window.steerUI = ui;

const $ = (id) => document.getElementById(id);
const frame = $("frame");
const overlay = $("overlay");
const ctx = overlay.getContext("2d");
let socket = null;
let sentAt = null; // performance.now() of the latest steer request
let drag = null; // points of the sketch or nudge being drawn (image pixels)

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

// ---------------------------------------------------------------- handlers
const HANDLERS = {
  ready(msg) {
    ui.width = msg.width; ui.height = msg.height;
    ui.scale = Math.min(4, MAX_DISPLAY / Math.max(msg.width, msg.height));
    frame.width = Math.round(msg.width * ui.scale); frame.height = Math.round(msg.height * ui.scale);
    overlay.width = frame.width; overlay.height = frame.height;
    $("env-name").textContent = `${msg.env} · policy ${msg.policy}`;
    for (const input of document.querySelectorAll("input[name=mode]")) {
      input.disabled = !msg.kinds.includes(input.value);
      input.parentElement.title = input.disabled ? "this env takes no such input" : "";
    }
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
    if (ui.lastInteraction) steer(ui.lastInteraction.kind, ui.lastInteraction.points); // show the new sampler's plans
  },
  plans(msg) {
    const t0 = performance.now();
    ui.plans = msg.plans; ui.chosen = msg.chosen; ui.collides = msg.collides;
    ui.interaction = msg.interaction; ui.interactionKind = msg.kind;
    ui.plansReceived += 1;
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
    frame.src = msg.image;
    ui.frames += 1;
    ui.agent = msg.agent;
    if (msg.why !== "ready") { ui.plans = []; ui.chosen = -1; ui.collides = null; }
    if (msg.why === "reset") { ui.interaction = []; ui.lastInteraction = null; $("error").hidden = true; }
    $("seed").value = msg.seed;
    const state = msg.done ? "ended — press Reset" : "running";
    const extra = [msg.mode && `mode ${msg.mode}`, msg.success && "success", msg.violation && "constraint violated"].filter(Boolean);
    $("s-episode").textContent = [state, ...extra].join(", ");
    draw();
  },
  playing(msg) { ui.playing = msg.playing; $("play").textContent = msg.playing ? "Pause" : "Play"; },
  error(msg) { sentAt = null; showError(msg.message); },
};

function applySettings(settings) {
  ui.settings = settings;
  $("sampler").value = settings.sampler;
  $("batch").value = settings.batch;
  $("guide_ratio").value = settings.guide_ratio ?? "";
  $("mcmc_steps").value = settings.mcmc_steps ?? "";
  $("execute").value = settings.execute ?? "";
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

function draw() {
  ctx.clearRect(0, 0, overlay.width, overlay.height);
  ctx.globalAlpha = 0.75;
  ui.plans.forEach((plan, i) => {
    if (i !== ui.chosen) polyline(plan, ui.collides && ui.collides[i] ? COLORS.collide : COLORS.plan, 1.5);
  });
  ctx.globalAlpha = 1;
  if (ui.chosen >= 0 && ui.plans[ui.chosen]) polyline(ui.plans[ui.chosen], COLORS.chosen, 3.5);
  ui.drawnPlans = ui.plans.length;
  const shown = drag && drag.mode === "sketch" ? drag.points : ui.interaction;
  if (shown.length === 1) {
    dot(shown[0], COLORS.sketch, 7);
  } else if (shown.length > 1) {
    polyline(shown, COLORS.sketch, 4);
    dot(shown[0], COLORS.sketch, 5);
  }
  if (drag && drag.mode === "nudge" && ui.agent) {
    ctx.setLineDash([6, 4]);
    polyline([ui.agent, drag.points[drag.points.length - 1]], COLORS.agent, 2);
    ctx.setLineDash([]);
    dot(drag.points[drag.points.length - 1], COLORS.agent, 6);
  }
}

// ------------------------------------------------------------------- input
function imagePixel(event) {
  const rect = overlay.getBoundingClientRect();
  const u = ((event.clientX - rect.left) / rect.width) * ui.width;
  const v = ((event.clientY - rect.top) / rect.height) * ui.height;
  return [Math.min(ui.width, Math.max(0, u)), Math.min(ui.height, Math.max(0, v))];
}

function mode() { return document.querySelector("input[name=mode]:checked").value; }

function steer(kind, points) {
  ui.lastInteraction = { kind, points };
  if (send({ type: "steer", kind, points })) sentAt = performance.now();
}

overlay.addEventListener("pointerdown", (event) => {
  if (!ui.ready) return;
  overlay.setPointerCapture(event.pointerId);
  drag = { mode: mode(), points: [imagePixel(event)] };
  draw();
});
overlay.addEventListener("pointermove", (event) => {
  if (!drag) return;
  const p = imagePixel(event);
  if (drag.mode === "sketch") {
    const last = drag.points[drag.points.length - 1];
    if (Math.hypot(p[0] - last[0], p[1] - last[1]) >= 0.5 && drag.points.length < 4096) drag.points.push(p);
  } else {
    drag.points = [p];
  }
  draw();
});
overlay.addEventListener("pointerup", (event) => {
  if (!drag) return;
  const { mode: m, points } = drag;
  const end = imagePixel(event);
  drag = null;
  if (m === "nudge") {
    send({ type: "nudge", to: end });
  } else if (m === "point" || points.length < 2) {
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
for (const input of document.querySelectorAll("input[name=mode]")) {
  input.addEventListener("change", () => {
    $("hint").textContent = {
      sketch: "Sketch mode: press and drag on the maze to draw a path; the steered plans follow.",
      point: "Point mode: click where the plans should go.",
      nudge: "Nudge mode: drag from anywhere to where the agent should be pushed (a physical correction).",
    }[mode()];
  });
}
$("resteer").addEventListener("click", () => {
  if (ui.lastInteraction) steer(ui.lastInteraction.kind, ui.lastInteraction.points); else steer("none", null);
});
$("reset").addEventListener("click", () => send({ type: "reset", seed: Number($("seed").value) || 0 }));
$("step").addEventListener("click", () => send({ type: "step" }));
$("play").addEventListener("click", () => send({ type: ui.playing ? "pause" : "play" }));

connect();
