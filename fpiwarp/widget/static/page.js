// The --web page's transport: the editor (editor.js) talking to the local
// server of fpiwarp/widget/server.py, with the token of the page's URL.
import { createEditor } from "./editor.js";

const token = new URLSearchParams(window.location.search).get("token") || "";
const headers = { "X-Fpiwarp-Token": token };
let editor = null;

async function check(response) {
  if (!response.ok) {
    let text = await response.text();
    try { text = JSON.parse(text).error || text; } catch (_) { /* plain text */ }
    throw new Error(text);
  }
  return response;
}

const transport = {
  async send(msg) {
    const r = await check(await fetch("api/message", {
      method: "POST", headers: { ...headers, "Content-Type": "application/json" }, body: JSON.stringify(msg),
    }));
    editor.setState(await r.json());
  },
  async getImage() {
    const r = await check(await fetch("api/image", { headers }));
    return { meta: JSON.parse(r.headers.get("X-Fpiwarp-Image")), buffer: await r.arrayBuffer() };
  },
  async getProgram(key) {
    const r = await check(await fetch(`api/program?key=${encodeURIComponent(key)}`, { headers }));
    return r.json();
  },
};

editor = createEditor(document.getElementById("fpiwarp"), transport);
// Reload the state from the server (a session replaced on the Python
// side): its overlays and view are taken as on a first load.
editor.reload = async () => {
  const r = await check(await fetch("api/state", { headers }));
  const state = await r.json();
  editor.restart();
  return editor.setState(state);
};
editor.reload();
