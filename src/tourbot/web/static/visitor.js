// The remote visitor page (Burgard et al., section 6.1): tours and exhibits on the left, the live
// 2D floor plan and the 3D view in the centre, exhibit information on the right.
import { Live, chatLine, getJSON, el } from "./live.js";
import { MapView } from "./mapview.js";

const $ = (id) => document.getElementById(id);
const state = { site: null, live: null, role: "watcher", slotEnds: null, slot: null, view3d: null };

// The message log, de-duplicated: a text already among the last few lines (two minutes at most)
// is not written again; its line moves to the top with a count ("moving", "blocked", "moving"...).
const REPEAT_LINES = 6;
const REPEAT_MS = 120000;
function message(text) {
  const log = $("messages");
  const now = Date.now();
  const lines = [...log.children].slice(0, REPEAT_LINES);
  const same = lines.find((n) => n.dataset.text === text && now - Number(n.dataset.at) < REPEAT_MS);
  if (same) {
    const count = Number(same.dataset.count) + 1;
    same.dataset.count = String(count);
    same.dataset.at = String(now);
    same.querySelector(".time").textContent = new Date().toLocaleTimeString();
    same.querySelector(".count").textContent = `×${count}`;
    log.prepend(same);
    return;
  }
  const line = el("div", { "data-text": text, "data-at": String(now), "data-count": "1" },
    el("span", { class: "time" }, new Date().toLocaleTimeString()), "  ", text, el("span", { class: "count" }, ""));
  log.prepend(line);
  while (log.children.length > 200) log.lastChild.remove();
}

function showExhibit(e) {
  const info = $("info");
  info.replaceChildren(el("h2", {}, e.name), el("p", {}, e.text || e.summary || ""),
    el("button", { id: "around", "data-around": e.slug, onclick: () => command({ type: "around", exhibit: e.slug }) },
      "Move around this exhibit"));
  for (const p of e.pictures) info.append(el("figure", {}, el("img", { src: p.url, alt: p.caption }), el("figcaption", {}, p.caption)));
  for (const l of e.links) info.append(el("p", {}, el("a", { href: l.url, target: "_blank", rel: "noopener" }, l.caption || l.url)));
}

function command(cmd) {
  if (state.role !== "holder") {
    message("Take control first (you will be queued if someone else is driving).");
    return;
  }
  state.live.send(cmd);
}

function renderSlot() {
  const s = state.slot;
  if (!s) return;
  let text;
  const left = state.slotEnds ? Math.max(0, Math.round(state.slotEnds - performance.now() / 1000)) : 0;
  const mmss = `${Math.floor(left / 60)}:${String(left % 60).padStart(2, "0")}`;
  if (s.staff_stop) text = "Stopped by staff";
  else if (s.role === "holder") text = `You control the robot: ${mmss} left${s.onboard ? " (visitors on site have precedence now)" : ""}`;
  else if (s.role === "queued") text = `You are number ${s.position} in the queue: about ${mmss} to wait`;
  else text = `Watching (${s.queue_length} waiting)`;
  $("slot").textContent = text;
  $("slot").dataset.role = s.role;
  for (const c of $("chat").elements) c.disabled = s.role !== "holder";
}

// The robots of the museum, each with its own queue: the visitor chooses one (the page reloads
// on it); the list says which are free and how many wait for each. The server sends the list
// over the live connection when it changes (never polled: every poll would cost the wire).
function listRobots(robots) {
  for (const r of robots) {
    let option = [...$("robot").options].find((o) => o.value === r.name);
    if (!option) { option = el("option", { value: r.name }, r.name); $("robot").append(option); }
    const busy = r.staff_stop ? "stopped by staff" : r.driven ? `driven, ${r.waiting} waiting` : "free";
    option.textContent = `${r.name} (${busy})`;
    option.dataset.driven = String(r.driven);
  }
}

async function takePhoto() {
  if (state.role !== "holder") {
    message("Take control first: the pictures are for the visitor driving the robot.");
    return;
  }
  const response = await fetch(`/api/robots/${encodeURIComponent(state.robot)}/photo`, { method: "POST", credentials: "same-origin" });
  if (!response.ok) {
    const body = await response.json().catch(() => ({}));
    message(`No picture: ${typeof body.detail === "string" ? body.detail : response.statusText}`);
    return;
  }
  const img = $("photo");
  if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
  img.src = URL.createObjectURL(await response.blob());
  $("photo-link").href = img.src; // the full 1280 x 960 picture in a tab of its own
  $("photo-caption").textContent = `${state.robot}'s camera, ${new Date().toLocaleTimeString()}`;
  $("photo-box").hidden = false;
}

function onStatus(status) {
  const before = state.role;
  state.slot = status.slot;
  state.role = status.slot.role;
  state.slotEnds = performance.now() / 1000 + status.slot.time_left;
  if (before !== "holder" && state.role === "holder") message("You have control of the robot.");
  if (before === "holder" && state.role !== "holder") message("Your control slot has ended.");
  renderSlot();
  const nav = status.nav;
  let text = nav.state;
  const exhibit = state.site.exhibits.find((e) => e.slug === nav.exhibit);
  if (nav.state === "arrived" && exhibit) text = `Arrived at ${exhibit.name}`;
  else if (exhibit) text = `${nav.state}: ${exhibit.name}`;
  if (nav.tour) text += ` (tour ${nav.tour}, ${nav.progress[0]}/${nav.progress[1]})`;
  if ($("state").textContent !== text) {
    $("state").textContent = text;
    message(text + (nav.message ? `: ${nav.message}` : ""));
  }
  if (nav.state === "arrived" && exhibit) showExhibit(exhibit);
}

// The server sends the planned path only when it changes: drop the part the robot has travelled.
function trimPath(map, bodies) {
  const robot = bodies.find((b) => b.id === 0);
  if (!robot || map.path.length < 2) return;
  let nearest = 1;
  let best = Infinity;
  for (let i = 1; i < map.path.length; i++) {
    const d = Math.hypot(map.path[i][0] - robot.x, map.path[i][1] - robot.y);
    if (d < best) { best = d; nearest = i; }
  }
  map.path = [[robot.x, robot.y], ...map.path.slice(nearest)];
}

async function start() {
  await getJSON("/api/session");
  const site = await getJSON("/api/site");
  state.site = site;
  $("title").textContent = `tourbot: ${site.name}`;
  for (const r of site.robots) $("robot").append(el("option", { value: r }, r));
  const asked = new URLSearchParams(location.search).get("robot");
  const robot = site.robots.includes(asked) ? asked : site.robots[0];
  state.robot = robot;
  $("robot").value = robot;
  $("robot").addEventListener("change", () => { location.search = `?robot=${encodeURIComponent($("robot").value)}`; });
  for (const t of site.tours) {
    $("tours").append(el("li", {}, el("button", { "data-tour": t.slug, onclick: () => command({ type: "tour", tour: t.slug }) }, t.name)));
  }
  for (const e of site.exhibits) {
    $("exhibits").append(el("li", {}, el("button", {
      "data-exhibit": e.slug,
      onclick: () => { showExhibit(e); command({ type: "exhibit", exhibit: e.slug }); },
    }, e.name)));
  }
  const map = new MapView($("map"), site, {
    onClick: (world, exhibit) => {
      if (exhibit) { showExhibit(exhibit); command({ type: "exhibit", exhibit: exhibit.slug }); }
      else { map.marker = world; command({ type: "goto", x: world.x, y: world.y }); }
    },
  });
  // ?debug=truth: the simulator's true people drawn hollow over the map, labelled as such (the
  // avatars are always the robot's own tracks)
  const debug = new URLSearchParams(location.search).get("debug") === "truth";
  if (debug) $("debug").hidden = false;
  state.live = new Live(robot, site.stream, {
    debug,
    onTruth: (points) => { map.truth = points; },
    onStatus,
    onPath: (points) => { map.path = points; },
    onObstacles: (m) => { map.obstacles = m.points; map.obstacleCell = m.cell; },
    onObjects: (objects) => { map.objects = objects; if (state.view3d) state.view3d.setObjects(objects); },
    onRobots: listRobots,
    onSay: (say) => message(`Robot says: ${say.text}`),
    onChat: (line) => chatLine($("chat-log"), line, "visitor"),
    onReply: (reply) => { if (reply.type === "error") message(`Refused: ${reply.message}`); },
    onOpen: () => message(`Connected to ${robot}.`),
  });
  $("book").addEventListener("click", () => state.live.send({ type: "book" }));
  $("leave").addEventListener("click", () => state.live.send({ type: "leave" }));
  $("stop").addEventListener("click", () => command({ type: "stop" }));
  $("photo-button").addEventListener("click", () => takePhoto().catch((e) => message(`No picture: ${e.message}`)));
  for (const id of ["book", "leave", "stop", "photo-button"]) $(id).disabled = false;
  $("chat").addEventListener("submit", (event) => {
    event.preventDefault();
    const text = $("chat-text").value.trim();
    if (text) state.live.send({ type: "chat", text });
    $("chat-text").value = "";
  });
  // No leave at pagehide: a reload or a second tab keeps the slot (the server holds it for a
  // grace time after the last page closes); "Leave" gives it up.
  if (site.three) {
    try {
      const { View3D } = await import("./view3d.js");
      state.view3d = new View3D($("view3d"), site, { screenUp: () => map.screenUp });
      state.view3d.setObjects(map.objects);
      for (const b of document.querySelectorAll("[data-preset]")) {
        b.addEventListener("click", () => state.view3d.setPreset(b.dataset.preset));
        b.disabled = false;
      }
    } catch (error) {
      message(`3D view unavailable: ${error.message}`);
    }
  } else {
    message("3D view unavailable: three.js is not installed on the server (npm ci).");
  }
  // At most 20 drawings a second: smooth enough for walking people, and a slow (software) renderer
  // never starves the page's heartbeat.
  let lastSlot = 0;
  let lastDraw = 0;
  const frame = (now) => {
    requestAnimationFrame(frame);
    if (now - lastDraw < 50) return;
    lastDraw = now;
    const bodies = state.live.scene();
    trimPath(map, bodies);
    map.draw(bodies);
    if (state.view3d) state.view3d.update(bodies);
    if (now - lastSlot > 1000) { renderSlot(); lastSlot = now; }
  };
  requestAnimationFrame(frame);
  state.map = map;
  state.message = message;
  window.tourbot = state; // for tests and curious visitors
}

start().catch((error) => message(`Cannot start: ${error.message}`));
