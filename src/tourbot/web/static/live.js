// The live connection of a page to one robot: binary stream in, JSON status and commands.
import { StreamDecoder } from "./stream.js";

const PENDING_S = 5; // a command waits at most this long for the connection to open
const PENDING_MAX = 16;

export class Live {
  constructor(robot, streamConfig, { screen = "web", debug = false, onStatus, onPath, onObstacles, onSay, onReply, onOpen, onTruth, onChat, onObjects, onRobots } = {}) {
    this.robot = robot;
    this.config = streamConfig;
    this.screen = screen;
    this.debug = debug;
    this.handlers = { onStatus, onPath, onObstacles, onSay, onReply, onOpen, onTruth, onChat, onObjects, onRobots };
    this.decoder = new StreamDecoder(streamConfig);
    this.offset = null; // local clock minus server clock (s), smallest seen: the least delayed
    this.ws = null;
    this.closed = false;
    this.retry = 500;
    this.bytes = 0; // payload received (binary stream and JSON texts)
    this.texts = 0; // of which JSON texts
    // Commands given while the connection is (re)opening, sent once it opens: a visitor's click
    // is never lost to a connection that is not up yet; one older than PENDING_S is dropped.
    this.pending = [];
    this.connect();
    this.heartbeat = setInterval(() => this.send({ type: "ping" }), 5000);
  }

  connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const query = this.screen === "onboard" ? "?screen=onboard" : this.debug ? "?debug=truth" : "";
    const ws = new WebSocket(`${scheme}://${location.host}/ws/${encodeURIComponent(this.robot)}${query}`);
    ws.binaryType = "arraybuffer";
    ws.onopen = () => {
      this.retry = 500;
      this.decoder = new StreamDecoder(this.config);
      if (this.handlers.onOpen) this.handlers.onOpen();
      const now = performance.now();
      for (const { command, at } of this.pending.splice(0)) {
        if (now - at <= PENDING_S * 1000) ws.send(JSON.stringify(command));
      }
    };
    ws.onmessage = (event) => this.receive(event.data);
    ws.onclose = () => {
      if (this.closed) return;
      setTimeout(() => this.connect(), this.retry);
      this.retry = Math.min(this.retry * 2, 10000);
    };
    this.ws = ws;
  }

  receive(data) {
    if (data instanceof ArrayBuffer) {
      this.bytes += data.byteLength;
      const t = this.decoder.feed(data);
      const offset = performance.now() / 1000 + performance.timeOrigin / 1000 - t;
      this.offset = this.offset === null ? offset : Math.min(offset, this.offset + 0.001);
      return;
    }
    this.bytes += data.length;
    this.texts += data.length;
    const message = JSON.parse(data);
    const h = this.handlers;
    if (message.type === "status" && h.onStatus) h.onStatus(message);
    else if (message.type === "path" && h.onPath) h.onPath(message.points);
    else if (message.type === "obstacles" && h.onObstacles) h.onObstacles(message);
    else if (message.type === "say" && h.onSay) h.onSay(message);
    else if (message.type === "truth" && h.onTruth) h.onTruth(message.people);
    else if (message.type === "chat" && h.onChat) h.onChat(message);
    else if (message.type === "objects" && h.onObjects) h.onObjects(message.objects);
    else if (message.type === "robots") { if (h.onRobots) h.onRobots(message.robots); }
    else if (h.onReply) h.onReply(message);
  }

  // The scene to draw now: server time = local time - offset, minus a small interpolation delay.
  scene(delay = 0.1) {
    if (this.offset === null) return [];
    const now = performance.timeOrigin / 1000 + performance.now() / 1000;
    return this.decoder.at(now - this.offset - delay);
  }

  send(command) {
    if (this.ws && this.ws.readyState === WebSocket.OPEN) this.ws.send(JSON.stringify(command));
    else if (command.type !== "ping" && !this.closed) {
      this.pending.push({ command, at: performance.now() });
      if (this.pending.length > PENDING_MAX) this.pending.shift();
    }
  }

  close() {
    this.closed = true;
    clearInterval(this.heartbeat);
    if (this.ws) this.ws.close();
  }
}

export async function getJSON(url, options = {}) {
  const response = await fetch(url, { credentials: "same-origin", ...options });
  const body = await response.json().catch(() => ({}));
  if (!response.ok) throw new Error(body.detail ? JSON.stringify(body.detail) : response.statusText);
  return body;
}

// The text channel's lines: each message once (a reconnection sends the conversation again), as
// text (never as HTML), newest last.
const SENDERS = { visitor: "Visitor", staff: "Staff", onboard: "At the robot" };
export function chatLine(log, message, me) {
  if (log.querySelector(`[data-id="${Number(message.id)}"]`)) return;
  const who = message.sender === me ? "You" : SENDERS[message.sender] || "?";
  log.append(el("div", { class: "chat-line", "data-id": String(Number(message.id)), "data-sender": message.sender },
    el("b", {}, `${who}: `), message.text));
  while (log.children.length > 100) log.firstChild.remove();
  log.scrollTop = log.scrollHeight;
}

export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") node.className = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const child of children) node.append(child);
  return node;
}
