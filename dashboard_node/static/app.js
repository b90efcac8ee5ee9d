// The aes-swarm dashboard page: draws the frames the server sends over a WebSocket and
// sends the user's control messages (dashboard_node/controls.py says what is accepted).
// No libraries: a canvas for the arena, the dial and the strip charts.

const HISTORY_S = 60;

// Everything the page knows; window.aesDashboard for the tests and the curious.
const state = {
  sheet: null,
  frame: null,
  frames: 0,               // frames received
  framesPerSecond: 0,
  draws: 0,                // pictures drawn, and the time spent drawing them [ms]
  drawMs: 0,
  drawn: null,             // what the last picture showed: {robots, springs, t}
  history: [],            // [t, psi, psi_heading, F]
  view: { cx: 0, cy: 0, scale: 300, follow: true },
  command: null,          // the swarm's command {direction, omega}, from every frame
  pending: {},             // what this viewer chose and the swarm does not show yet
  dragging: null,          // the direction under the pointer while the dial is dragged
  sent: [],                // the controls awaiting their result, oldest first
  connected: false,
  results: [],
};
window.aesDashboard = state;

const $ = (id) => document.getElementById(id);
// The token comes with the URL the dashboard printed; it goes on the WebSocket's URL
// (the server also keeps it in a cookie) and leaves the address bar and history.
const token = new URLSearchParams(location.search).get("token");
if (token) history.replaceState(null, "", location.pathname);
let socket = null;

// --------------------------------------------------------------------- connection

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const query = token ? `?token=${encodeURIComponent(token)}` : "";
  socket = new WebSocket(`${scheme}://${location.host}/ws${query}`);
  socket.onopen = () => { state.connected = true; };
  socket.onclose = () => {
    state.connected = false;
    state.sent = [];
    status("disconnected: retrying…");
    setTimeout(connect, 1000);
  };
  socket.onmessage = (event) => receive(JSON.parse(event.data));
}

function send(message) {
  if (!socket || socket.readyState !== WebSocket.OPEN) {
    note(false, "not connected");
    return false;
  }
  socket.send(JSON.stringify(message));
  state.sent.push(message);  // the server answers each message once, in order
  return true;
}

function receive(message) {
  if (message.type === "sheet") {
    state.sheet = message;
    state.history = message.history || [];
    gainRows(message.gains || []);
    state.fitted = false;
  } else if (message.type === "frame") {
    state.frame = message;
    state.frames += 1;
    remember(message);
    if (state.view.follow && message.centroid) {
      state.view.cx = message.centroid[0];
      state.view.cy = message.centroid[1];
    }
    if (!state.fitted && message.x) fit(message);
    if (message.direction) settle({ direction: message.direction, omega: message.omega });
    for (const [name, value] of Object.entries(message.gains || {})) {
      const field = $(`gain-${name}`);
      if (field) field.placeholder = value == null ? "" : String(value);
    }
    schedule();
  } else if (message.type === "access" && !message.control) {
    note(false, "viewing only: open the URL the dashboard printed (with ?token=…) to steer");
  } else if (message.type === "result") {
    const control = state.sent.shift();
    if (!message.ok && control && control.type === "drive") forget(control);
    note(message.ok, message.message);
  }
}

// The swarm's command, whoever set it (this page, another viewer, ros2 topic pub):
// the page always shows it. A choice of this viewer stays "pending" until the
// swarm's command shows it; one the swarm never takes is dropped after PENDING_S.
const PENDING_S = 10;
const same = (a, b) => Math.abs(a - b) < 1e-3;

function settle(command) {
  state.command = command;
  const p = state.pending;
  const now = performance.now() / 1000;
  if (p.direction && same(p.direction[0], command.direction[0]) &&
      same(p.direction[1], command.direction[1])) delete p.direction;
  if (p.omega != null && command.omega != null && same(p.omega, command.omega)) delete p.omega;
  if ((p.direction || p.omega != null) && now - p.at > PENDING_S) {
    note(false, "the swarm did not take the command; it shows what it does");
    state.pending = {};
  }
  showOmega();
}

function forget(control) {
  if (control.direction) delete state.pending.direction;
  if (control.omega != null) delete state.pending.omega;
  showOmega();
}

function showOmega() {
  const slider = $("omega");
  const omega = state.command ? state.command.omega : null;
  if (!slider.matches(":active") && state.pending.omega == null && omega != null) {
    slider.value = omega;
  }
  $("omega-value").textContent = fmt(omega);
  const p = state.pending, parts = [];
  if (p.direction) parts.push(`v_d → (${fmt(p.direction[0])}, ${fmt(p.direction[1])})`);
  if (p.omega != null) parts.push(`ω → ${fmt(p.omega)} rad/s`);
  $("pending").textContent = parts.length ? `pending: ${parts.join(", ")}` : "";
}

function remember(frame) {
  const m = frame.metrics || {};
  if (frame.t == null || m.total_force == null) return;
  const last = state.history[state.history.length - 1];
  if (last && frame.t <= last[0]) {
    if (frame.t < last[0] - 1) state.history = [];  // a new clock
    else return;
  }
  state.history.push([frame.t, m.alignment, m.heading_order, m.total_force]);
  while (state.history.length && state.history[0][0] < frame.t - HISTORY_S) state.history.shift();
}

setInterval(() => {  // frames per second, for the status line
  state.framesPerSecond = state.frames - (state.lastCount || 0);
  state.lastCount = state.frames;
}, 1000);

// --------------------------------------------------------------------- drawing

function status(text) { $("status").textContent = text; }

function fmt(value, digits = 2) { return value == null ? "–" : Number(value).toFixed(digits); }

function drawStatus() {
  const f = state.frame;
  if (!f) return;
  const silent = f.silent ? f.silent.length : 0;
  status(
    `t = ${fmt(f.t, 1)} s · real-time factor ${fmt(f.rtf, 2)} · robots ${f.n - silent} alive` +
    `${silent ? `, ${silent} silent` : ""} · ${state.sheet ? state.sheet.scenario : ""} · ` +
    `${f.enabled === false ? "disabled" : "enabled"} · ψ ${fmt(f.metrics.alignment)} · ` +
    `contacts ${fmt(f.contacts_per_s, 1)}/s · closest ` +
    `${f.min_centre_distance == null ? "–" : fmt(1000 * f.min_centre_distance, 1)} mm · ` +
    `${state.framesPerSecond} updates/s`
  );
  $("enable").textContent = f.enabled === false ? "enable" : "disable";
}

let drawPending = false;
function schedule() {
  if (drawPending) return;
  drawPending = true;
  requestAnimationFrame(() => { drawPending = false; draw(); });
}

function draw() {
  const start = performance.now();
  drawStatus();
  drawArena();
  drawDial();
  drawChart("chart-psi", 1, "force alignment ψ", [0, 1]);
  drawChart("chart-order", 2, "heading order ψ_heading", [0, 1]);
  drawChart("chart-force", 3, "total force F", null);
  state.draws += 1;
  state.drawMs += performance.now() - start;
}

// Colours in a few levels, so that the canvas fills and strokes each level in one path:
// one call per level instead of one per robot or spring (1000 robots stay fast).
const LEVELS = 10;
const level = (value) => Math.min(LEVELS, Math.max(0, Math.round(value * LEVELS)));
const robotColor = (k) => `hsl(${(120 * k) / LEVELS}, 75%, 42%)`;
const springColor = (k) => {
  const a = k / LEVELS;
  return `rgb(${187 + 24 * a}, ${187 * (1 - a)}, ${187 * (1 - a)})`;
};

function drawArena() {
  const canvas = $("arena");
  const w = (canvas.width = canvas.clientWidth);
  const h = (canvas.height = canvas.clientHeight);
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, w, h);
  const f = state.frame;
  if (!f || !f.x) return;
  const { cx, cy, scale } = state.view;
  const sx = (x) => w / 2 + (x - cx) * scale;
  const sy = (y) => h / 2 - (y - cy) * scale;
  drawWallsAndObstacles(ctx, sx, sy, scale);
  // springs, tinted by strain (full red at 30 %)
  const springs = state.sheet && f.strain && state.sheet.springs.length === f.strain.length;
  if (springs) {
    const paths = Array.from({ length: LEVELS + 1 }, () => new Path2D());
    state.sheet.springs.forEach(([i, j], k) => {
      const path = paths[level(Math.abs(f.strain[k]) / 0.3)];
      path.moveTo(sx(f.x[i]), sy(f.y[i]));
      path.lineTo(sx(f.x[j]), sy(f.y[j]));
    });
    paths.forEach((path, k) => {
      ctx.strokeStyle = springColor(k);
      ctx.lineWidth = 1 + k / LEVELS;
      ctx.stroke(path);
    });
  }
  // the centroid's trail
  if (f.trail && f.trail.length > 1) {
    ctx.strokeStyle = "#c62828";
    ctx.lineWidth = 2;
    ctx.beginPath();
    f.trail.forEach(([x, y], k) => (k ? ctx.lineTo(sx(x), sy(y)) : ctx.moveTo(sx(x), sy(y))));
    ctx.stroke();
  }
  // robots: Mona-sized discs (Ø 80 mm) coloured by psi_i, a line along the heading;
  // silent ones grey with a dashed rim
  const silent = new Set(f.silent || []);
  const r = Math.max(2, 0.04 * scale);
  const bodies = Array.from({ length: LEVELS + 1 }, () => new Path2D());
  const grey = new Path2D(), rims = new Path2D(), greyRims = new Path2D();
  for (let i = 0; i < f.x.length; i++) {
    const x = sx(f.x[i]), y = sy(f.y[i]);
    const disc = silent.has(i) ? grey : bodies[level(f.psi[i])];
    disc.moveTo(x + r, y);
    disc.arc(x, y, r, 0, 2 * Math.PI);
    const rim = silent.has(i) ? greyRims : rims;
    rim.moveTo(x + r, y);
    rim.arc(x, y, r, 0, 2 * Math.PI);
    rim.moveTo(x, y);
    rim.lineTo(x + 1.5 * r * Math.cos(f.theta[i]), y - 1.5 * r * Math.sin(f.theta[i]));
  }
  bodies.forEach((path, k) => { ctx.fillStyle = robotColor(k); ctx.fill(path); });
  ctx.fillStyle = "#9e9e9e";
  ctx.fill(grey);
  ctx.lineWidth = 1;
  ctx.strokeStyle = "#212121";
  ctx.stroke(rims);
  ctx.strokeStyle = "#616161";
  ctx.setLineDash([3, 2]);
  ctx.stroke(greyRims);
  ctx.setLineDash([]);
  state.drawn = { robots: f.x.length, springs: springs ? f.strain.length : 0, t: f.t };
  // rotation centre and desired direction
  if (f.center) {
    const x = sx(f.center[0]), y = sy(f.center[1]);
    ctx.strokeStyle = "#7b1fa2";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(x - 6, y - 6); ctx.lineTo(x + 6, y + 6);
    ctx.moveTo(x - 6, y + 6); ctx.lineTo(x + 6, y - 6);
    ctx.stroke();
  }
  if (f.centroid && f.direction && (f.direction[0] || f.direction[1])) {
    arrow(ctx, sx(f.centroid[0]), sy(f.centroid[1]), 60 * f.direction[0], -60 * f.direction[1], "#1565c0");
  }
}

// The scenario's walls (a dark rectangle) and obstacles (dark circles and boxes).
function drawWallsAndObstacles(ctx, sx, sy, scale) {
  const s = state.sheet;
  if (!s) return;
  ctx.fillStyle = ctx.strokeStyle = "#333333";
  if (s.walls && s.walls.length === 4) {
    const [x0, x1, y0, y1] = s.walls;
    ctx.lineWidth = 4;
    ctx.strokeRect(sx(x0), sy(y1), (x1 - x0) * scale, (y1 - y0) * scale);
  }
  const shapes = new Path2D();
  for (const [x, y, r] of s.circles || []) {
    shapes.moveTo(sx(x) + r * scale, sy(y));
    shapes.arc(sx(x), sy(y), r * scale, 0, 2 * Math.PI);
  }
  for (const [x0, x1, y0, y1] of s.boxes || []) {
    shapes.rect(sx(x0), sy(y1), (x1 - x0) * scale, (y1 - y0) * scale);
  }
  ctx.fill(shapes);
}

function arrow(ctx, x, y, dx, dy, color) {
  const len = Math.hypot(dx, dy);
  if (len < 1) return;
  ctx.strokeStyle = ctx.fillStyle = color;
  ctx.lineWidth = 3;
  ctx.beginPath();
  ctx.moveTo(x, y);
  ctx.lineTo(x + dx, y + dy);
  ctx.stroke();
  const ux = dx / len, uy = dy / len;
  ctx.beginPath();
  ctx.moveTo(x + dx, y + dy);
  ctx.lineTo(x + dx - 10 * ux + 6 * uy, y + dy - 10 * uy - 6 * ux);
  ctx.lineTo(x + dx - 10 * ux - 6 * uy, y + dy - 10 * uy + 6 * ux);
  ctx.fill();
}

function drawDial() {
  const canvas = $("dial");
  const ctx = canvas.getContext("2d");
  const R = canvas.width / 2 - 8, c = canvas.width / 2;
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.strokeStyle = "#90a4ae";
  ctx.lineWidth = 1;
  ctx.beginPath();
  ctx.arc(c, c, R, 0, 2 * Math.PI);
  ctx.moveTo(c - R, c); ctx.lineTo(c + R, c);
  ctx.moveTo(c, c - R); ctx.lineTo(c, c + R);
  ctx.stroke();
  ctx.fillStyle = "#607d8b";
  ctx.fillText("N", c - 3, 12); ctx.fillText("E", 2 * c - 10, c + 4);
  // the swarm's command, solid; this viewer's choice not yet taken, dashed
  const chosen = state.dragging || state.pending.direction;
  if (chosen) {
    ctx.setLineDash([4, 3]);
    arrow(ctx, c, c, R * chosen[0], -R * chosen[1], "#ef6c00");
    ctx.setLineDash([]);
  }
  const command = state.command ? state.command.direction : null;
  if (command) arrow(ctx, c, c, R * command[0], -R * command[1], "#1565c0");
  $("dir-x").textContent = fmt(command && command[0]);
  $("dir-y").textContent = fmt(command && command[1]);
}

function drawChart(id, column, label, range) {
  const canvas = $(id);
  const ctx = canvas.getContext("2d");
  const w = canvas.width, h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  const rows = state.history.filter((row) => row[column] != null);
  ctx.fillStyle = "#455a64";
  ctx.fillText(label + (rows.length ? ` ${fmt(rows[rows.length - 1][column])}` : ""), 4, 11);
  if (rows.length < 2) return;
  const t1 = rows[rows.length - 1][0], t0 = t1 - HISTORY_S;
  const values = rows.map((row) => row[column]);
  const lo = range ? range[0] : Math.min(...values), hi = range ? range[1] : Math.max(...values);
  const span = hi - lo || 1;
  ctx.strokeStyle = "#1565c0";
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  rows.forEach((row, k) => {
    const x = ((row[0] - t0) / HISTORY_S) * w, y = h - 4 - ((row[column] - lo) / span) * (h - 18);
    k ? ctx.lineTo(x, y) : ctx.moveTo(x, y);
  });
  ctx.stroke();
}

// Zoom so that the whole sheet fills about 60 % of the arena (once per sheet).
function fit(frame) {
  const canvas = $("arena");
  const span = (values) => Math.max(...values) - Math.min(...values);
  const extent = Math.max(span(frame.x), span(frame.y), 0.2);
  const size = Math.min(canvas.clientWidth, canvas.clientHeight) || 600;
  state.view.scale = Math.min(1000, Math.max(5, (0.6 * size) / extent));
  state.fitted = true;
}

// One row per gain the server accepts (the sheet lists them: dashboard_node/view.py).
function gainRows(names) {
  if ($("gains").querySelector(".gain")) return;
  for (const name of names) {
    const row = document.createElement("div");
    row.className = "gain";
    row.innerHTML = `<label for="gain-${name}">${name}</label>` +
      `<input id="gain-${name}" type="number" step="any"><button type="button">set</button>`;
    row.querySelector("button").addEventListener("click", () => {
      const text = row.querySelector("input").value.trim();
      const value = Number(text);
      if (text === "" || !Number.isFinite(value)) { note(false, `${name}: ${text || "(empty)"} is not a number`); return; }
      send({ type: "gain", name, value });
    });
    $("gains").appendChild(row);
  }
}

function note(ok, text) {
  state.results.push({ ok, text });
  const item = document.createElement("li");
  item.className = ok ? "ok" : "error";
  item.textContent = text;
  $("messages").prepend(item);
}

// --------------------------------------------------------------------- controls

function setDirectionFrom(event) {
  const canvas = $("dial");
  const rect = canvas.getBoundingClientRect();
  const R = canvas.width / 2 - 8, c = canvas.width / 2;
  let x = (event.clientX - rect.left - c) / R, y = -(event.clientY - rect.top - c) / R;
  const len = Math.hypot(x, y);
  if (len > 1) { x /= len; y /= len; }
  state.dragging = [Math.round(x * 100) / 100, Math.round(y * 100) / 100];
  drawDial();
}

// A drive message with only what the viewer changed: the direction or ω.
function drive(change) {
  const control = { type: "drive", ...change };
  if (!send(control)) return;
  Object.assign(state.pending, change, { at: performance.now() / 1000 });
  showOmega();
  schedule();
}

function setup() {
  const dial = $("dial");
  let dragging = false;
  dial.addEventListener("pointerdown", (e) => { dragging = true; setDirectionFrom(e); });
  dial.addEventListener("pointermove", (e) => dragging && setDirectionFrom(e));
  dial.addEventListener("pointerup", () => {
    if (!dragging) return;
    dragging = false;
    const direction = state.dragging;
    state.dragging = null;
    drive({ direction });
  });
  $("stop-drive").addEventListener("click", () => drive({ direction: [0, 0] }));
  $("omega").addEventListener("input", () => {
    $("pending").textContent = `ω → ${fmt($("omega").value)} rad/s (release to send)`;
  });
  $("omega").addEventListener("change", () => drive({ omega: Number($("omega").value) }));
  $("enable").addEventListener("click", () =>
    send({ type: "enable", enabled: state.frame ? state.frame.enabled === false : false }));
  for (const action of ["pause", "resume", "reset"]) {
    $(action).addEventListener("click", () => send({ type: "sim", action }));
  }
  // pan and zoom; panning stops following the swarm
  const arena = $("arena");
  let last = null;
  arena.addEventListener("pointerdown", (e) => { last = [e.clientX, e.clientY]; });
  window.addEventListener("pointerup", () => { last = null; });
  arena.addEventListener("pointermove", (e) => {
    if (!last) return;
    state.view.cx -= (e.clientX - last[0]) / state.view.scale;
    state.view.cy += (e.clientY - last[1]) / state.view.scale;
    last = [e.clientX, e.clientY];
    state.view.follow = false;
    $("follow").checked = false;
    schedule();
  });
  arena.addEventListener("wheel", (e) => {
    e.preventDefault();
    state.view.scale = Math.min(5000, Math.max(5, state.view.scale * Math.pow(1.1, -e.deltaY / 100)));
    schedule();
  }, { passive: false });
  $("follow").addEventListener("change", () => { state.view.follow = $("follow").checked; });
  connect();
}

setup();
