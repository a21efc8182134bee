// Staff authoring (Burgard et al., section 7.1): exhibits with text, pictures and links, placed on
// the map with a click; tours as ordered exhibits; visit statistics; the staff stop.
import { chatLine, getJSON, el } from "./live.js";
import { MapView } from "./mapview.js";

const $ = (id) => document.getElementById(id);
let site = null;
let map = null;

function post(url, body, method = "POST") {
  return getJSON(url, {
    method,
    headers: { "Content-Type": "application/json" },
    body: body === undefined ? undefined : JSON.stringify(body),
  });
}

function note(text) { $("message").textContent = text; }

function lines(text) {
  return text.split("\n").map((l) => l.trim()).filter(Boolean).map((l) => {
    const [url, ...caption] = l.split(/\s+/);
    return { url, caption: caption.join(" ") };
  });
}

function edit(e) {
  const f = $("exhibit").elements;
  for (const k of ["slug", "name", "summary", "text", "x", "y", "theta"]) f[k].value = e[k];
  f.pictures.value = e.pictures.map((p) => `${p.url} ${p.caption}`).join("\n");
  f.links.value = e.links.map((p) => `${p.url} ${p.caption}`).join("\n");
  map.marker = { x: e.x, y: e.y };
}

async function reload() {
  site = await getJSON("/api/site");
  if (!map) {
    map = new MapView($("map"), site, {
      onClick: (world) => {
        const f = $("exhibit").elements;
        f.x.value = world.x.toFixed(2);
        f.y.value = world.y.toFixed(2);
        map.marker = world;
      },
    });
    const draw = () => { map.draw([]); requestAnimationFrame(draw); };
    requestAnimationFrame(draw);
  }
  map.exhibits = site.exhibits;
  $("exhibits").replaceChildren(
    el("tr", {}, el("th", {}, "slug"), el("th", {}, "name"), el("th", {}, "x"), el("th", {}, "y")),
    ...site.exhibits.map((e) => el("tr", { onclick: () => edit(e) },
      el("td", {}, e.slug), el("td", {}, e.name), el("td", {}, e.x.toFixed(2)), el("td", {}, e.y.toFixed(2)))),
  );
  $("tours").replaceChildren(...site.tours.map((t) => el("tr", {}, el("td", {}, t.name), el("td", {}, t.exhibits.join(" → ")))));
  $("robots").replaceChildren(...site.robots.map((r) => el("p", {}, `${r} `,
    el("button", { onclick: () => post(`/api/robots/${r}/staff-stop`).then(() => note(`${r} stopped`)) }, "Staff stop"),
    el("button", { onclick: () => post(`/api/robots/${r}/staff-release`).then(() => note(`${r} released`)) }, "Release"))));
  const stats = await getJSON("/api/admin/stats");
  $("stats").replaceChildren(...Object.entries(stats.visits).map(([slug, n]) => el("tr", {}, el("td", {}, slug), el("td", {}, String(n)))));
}

// The text channel: the chosen robot's messages, read every 2 s; the answer goes to the visitor in
// control of that robot (messages of earlier visitors are shown greyed).
let chatRobot = null;
async function readChat() {
  const robot = $("chat-robot").value;
  if (!robot) return;
  const log = $("chat-log");
  if (robot !== chatRobot) { log.replaceChildren(); chatRobot = robot; }
  const chat = await getJSON(`/api/admin/robots/${encodeURIComponent(robot)}/chat`);
  for (const m of chat.messages) {
    chatLine(log, m, "staff");
    log.querySelector(`[data-id="${Number(m.id)}"]`).classList.toggle("earlier", !m.current);
  }
  $("chat-note").textContent = chat.holder ? "" : "No visitor is driving this robot now.";
}

async function loggedIn(user) {
  $("login-box").hidden = true;
  $("work").hidden = false;
  $("logout").hidden = false;
  $("who").textContent = user;
  await reload();
  $("chat-robot").replaceChildren(...site.robots.map((r) => el("option", { value: r }, r)));
  $("talk").hidden = false;
  $("chat-robot").addEventListener("change", () => readChat().catch(() => {}));
  readChat().catch(() => {});
  setInterval(() => readChat().catch(() => {}), 2000);
}

$("chat").addEventListener("submit", async (event) => {
  event.preventDefault();
  const text = $("chat-text").value.trim();
  if (!text) return;
  try {
    await post(`/api/admin/robots/${encodeURIComponent($("chat-robot").value)}/chat`, { text });
    $("chat-text").value = "";
    await readChat();
  } catch (error) { $("chat-note").textContent = `not sent: ${error.message}`; }
});

$("login").addEventListener("submit", async (event) => {
  event.preventDefault();
  try {
    const r = await post("/api/login", { username: $("username").value, password: $("password").value });
    await loggedIn(r.user);
  } catch (error) {
    $("login-error").textContent = `Login failed: ${error.message}`;
  }
});

$("logout").addEventListener("click", async () => { await post("/api/logout"); location.reload(); });

$("exhibit").addEventListener("submit", async (event) => {
  event.preventDefault();
  const f = $("exhibit").elements;
  try {
    await post("/api/admin/exhibits", {
      slug: f.slug.value, name: f.name.value, summary: f.summary.value, text: f.text.value,
      x: Number(f.x.value), y: Number(f.y.value), theta: Number(f.theta.value || 0),
      pictures: lines(f.pictures.value), links: lines(f.links.value),
    });
    note(`saved ${f.slug.value}`);
    await reload();
  } catch (error) { note(`not saved: ${error.message}`); }
});

$("delete").addEventListener("click", async () => {
  const slug = $("exhibit").elements.slug.value;
  try { await post(`/api/admin/exhibits/${encodeURIComponent(slug)}`, undefined, "DELETE"); note(`deleted ${slug}`); await reload(); }
  catch (error) { note(`not deleted: ${error.message}`); }
});

$("tour").addEventListener("submit", async (event) => {
  event.preventDefault();
  const f = $("tour").elements;
  try {
    await post("/api/admin/tours", {
      slug: f.slug.value, name: f.name.value, exhibits: f.exhibits.value.split(",").map((s) => s.trim()).filter(Boolean),
    });
    note(`saved tour ${f.slug.value}`);
    await reload();
  } catch (error) { note(`tour not saved: ${error.message}`); }
});

getJSON("/api/admin/stats").then(() => loggedIn("staff")).catch(() => {});

// for tests and benchmarks: the map (world <-> canvas) once it is drawn
window.tourbot = { get map() { return map; } };
