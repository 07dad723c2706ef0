/* glider-cosim explore: the three FMUs' WebAssembly modules under a co-simulation master
 * in the page (written by glider_cosim.runner.explore; the data object GLIDER_DATA is
 * inserted before this script).
 *
 * The modules are the core modules inside the FMUs' FMI-LS-WASM components (the model, the
 * native back end and the FMI layer, and the canonical-ABI glue of the world
 * co-simulation-fmu): this small host speaks that ABI for the few calls a run makes
 * (instantiate, set/get, enter/exit initialisation, do-step, drop), the master repeats
 * what our Python master does: Initialization Mode's inputs (GLIDER_DATA.init_order), then
 * the exchange it plans (GLIDER_DATA.plans: its order of gets and sets per coupling); the
 * metrics are those of glider_cosim.runner.metrics.
 *
 * API: window.glider.ready (a promise), window.glider.simulate(settings) -> {time: [...],
 * "plant.theta_g": [...], ..., metrics: {...}, status, messages, elapsed_ms},
 * window.glider.defaults (the scenario's settings). */
"use strict";
(function () {
  const D = GLIDER_DATA;
  const IFACE = "fmi:fmi3/co-simulation@3.0.0#";
  const M = IFACE + "[method]co-simulation-instance.";
  const STATUS = ["ok", "warning", "discard", "error", "fatal"];
  const utf8 = new TextEncoder();
  const text = new TextDecoder();

  function bytesOf(b64) {
    const s = atob(b64);
    const out = new Uint8Array(s.length);
    for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
    return out;
  }

  /* One model's module: its exports, called in the canonical ABI. */
  class Model {
    constructor(instance, messages) {
      this.x = instance.exports;
      this.messages = messages;
    }
    static async load(b64, messages) {
      let self = null;
      const imports = {
        "fmi:fmi3/callbacks@3.0.0": {
          "log-message": (np, nl, st, cp, cl, mp, ml) => {
            const m = self.x.memory.buffer;
            messages.push({
              instance: text.decode(new Uint8Array(m, np, nl)),
              status: STATUS[st],
              category: text.decode(new Uint8Array(m, cp, cl)),
              message: text.decode(new Uint8Array(m, mp, ml)),
            });
          },
        },
        "[export]fmi:fmi3/co-simulation@3.0.0": {
          "[resource-new]co-simulation-instance": (rep) => rep,
        },
      };
      const { instance } = await WebAssembly.instantiate(bytesOf(b64), imports);
      self = new Model(instance, messages);
      if (self.x._initialize) self.x._initialize();
      return self;
    }
    alloc(size, align) {
      return this.x.cabi_realloc(0, 0, align, size);
    }
    str(s) {
      const b = utf8.encode(s);
      const p = this.alloc(b.length, 1);
      new Uint8Array(this.x.memory.buffer, p, b.length).set(b);
      return [p, b.length];
    }
    u32s(a) {
      const p = this.alloc(4 * a.length, 4);
      new Uint32Array(this.x.memory.buffer, p, a.length).set(a);
      return p;
    }
    instantiate(name, token) {
      const [np, nl] = this.str(name);
      const [tp, tl] = this.str(token);
      const r = this.x[IFACE + "[static]co-simulation-instance.instantiate-co-simulation"](
        np, nl, tp, tl, 0, 0, 0, 0, 0, 0, 0, 0);
      const v = new DataView(this.x.memory.buffer);
      return v.getUint8(r) ? v.getInt32(r + 4, true) : null;
    }
    free(h) {
      this.x[IFACE + "[dtor]co-simulation-instance"](h);
    }
    set(h, type, vrs, values) {
      const n = vrs.length, vp = this.u32s(vrs);
      let p;
      if (type === "Real") {
        p = this.alloc(8 * n, 8);
        new Float64Array(this.x.memory.buffer, p, n).set(values);
        return this.x[M + "set-float64"](h, vp, n, p, n);
      }
      if (type === "Integer") {
        p = this.alloc(4 * n, 4);
        new Int32Array(this.x.memory.buffer, p, n).set(values);
        return this.x[M + "set-int32"](h, vp, n, p, n);
      }
      p = this.alloc(n, 1);
      new Uint8Array(this.x.memory.buffer, p, n).set(values.map((b) => (b ? 1 : 0)));
      return this.x[M + "set-boolean"](h, vp, n, p, n);
    }
    /* the values into out (a plain array), or the status (> 1) */
    get(h, type, vrs, out) {
      const n = vrs.length;
      const fn = { Real: "get-float64", Integer: "get-int32", Boolean: "get-boolean" }[type];
      const r = this.x[M + fn](h, this.u32s(vrs), n);
      const v = new DataView(this.x.memory.buffer);
      if (v.getUint8(r)) return v.getUint8(r + 4);
      const p = v.getUint32(r + 4, true);
      const buf = this.x.memory.buffer;
      const a = type === "Real" ? new Float64Array(buf, p, n)
        : type === "Integer" ? new Int32Array(buf, p, n) : new Uint8Array(buf, p, n);
      for (let i = 0; i < n; i++) out[i] = a[i];
      return 0;
    }
    enter(h, t0) {
      return this.x[M + "enter-initialization-mode"](h, 0, 0.0, t0, 0, 0.0);
    }
    exit(h) {
      return this.x[M + "exit-initialization-mode"](h);
    }
    /* 0: stepped; 2: the model stopped the simulation (discard); else the status */
    step(h, t, dt) {
      const r = this.x[M + "do-step"](h, t, dt, 1);
      const v = new DataView(this.x.memory.buffer);
      if (v.getUint8(r)) return v.getUint8(r + 8);
      return v.getUint8(r + 17) ? 2 : 0;
    }
  }

  /* ------------------------------------------------------------ the run */
  const LAWS = { "open loop": 0, passivity: 1, P: 2, PI: 3 };
  const defaults = Object.assign({}, D.defaults);

  function parameters(s) {
    const p = JSON.parse(JSON.stringify(D.parameters));
    const put = (inst, name, value) => {
      p[inst] = p[inst] || {};
      p[inst][name] = value;
    };
    put("controller", "law", LAWS[s.law]);
    for (const k of ["K_c", "K_P", "K_I"]) put("controller", k, s[k]);
    put("plant", "noise_std", s.noise_std);
    put("plant", "tau_servo", s.tau_servo);
    put("plant", "theta_g_0", s.theta_g_0);
    put("observer", "f_cutoff", s.f_cutoff);
    return p;
  }

  function simulate(settings) {
    const t0clock = performance.now();
    const s = Object.assign({}, defaults, settings || {});
    if (!(s.law in LAWS)) throw new Error(`law ${JSON.stringify(s.law)} is invalid: expected one of ${Object.keys(LAWS).join(", ")}`);
    const plan = D.plans[s.coupling];
    if (!plan) throw new Error(`coupling ${JSON.stringify(s.coupling)} is invalid: expected gauss-seidel or jacobi`);
    const h = D.step, t0 = D.t0;
    const n = Math.round((s.stop_time - t0) / h);
    if (!(n >= 1 && n <= 1e6)) throw new Error(`stop_time = ${s.stop_time} is invalid: expected a time after the start`);
    const messages = [];
    for (const m of Object.values(models)) m.messages.length = 0;
    const params = parameters(s);
    const handles = {};
    let status = "ok", failure = "";
    const fail = (inst, call, st) => {
      status = st === 2 ? "stopped" : "error";
      const log = models[inst].messages;  // its first error or discard says why
      const last = (log.find((m) => m.status === "error" || m.status === "discard") || log[log.length - 1] || {}).message || "";
      failure = `${inst}: ${call} returned ${STATUS[st] || st}${last ? ": " + last : ""}`;
    };
    const values = {};
    for (const name of D.needed) values[name] = 0.0;
    const cols = { time: new Array(n + 1) };
    for (const c of D.record) cols[c] = new Array(n + 1);
    let rows = 0;
    try {
      for (const inst of D.instances) {
        const m = models[inst];
        const hd = m.instantiate(inst, D.guids[inst]);
        if (hd === null) { fail(inst, "instantiate-co-simulation", 3); return finish(); }
        handles[inst] = hd;
      }
      for (const inst of D.instances) {
        const m = models[inst], hd = handles[inst];
        for (const [name, value] of Object.entries(params[inst] || {})) {
          const v = D.variables[inst][name];
          const st = m.set(hd, v.type, [v.vr], [value]);
          if (st > 1) { fail(inst, `set ${name}`, st); return finish(); }
        }
        const st = m.enter(hd, t0);
        if (st > 1) { fail(inst, "enter-initialization-mode", st); return finish(); }
      }
      // Initialization Mode (master.initial): the driven inputs, then each connected input
      // from its source in the order of the <InitialUnknowns> dependencies, then every exit
      for (const g of D.driven) {
        const st = models[g.inst].set(handles[g.inst], "Real", g.vrs, g.values);
        if (st > 1) { fail(g.inst, "set driven inputs", st); return finish(); }
      }
      const one = [0];
      for (const o of D.init_order) {
        let st = models[o.src].get(handles[o.src], o.type, [o.svr], one);
        if (st > 1) { fail(o.src, "get in Initialization Mode", st); return finish(); }
        st = models[o.dst].set(handles[o.dst], o.type, [o.dvr], [one[0]]);
        if (st > 1) { fail(o.dst, "set in Initialization Mode", st); return finish(); }
      }
      for (const inst of D.instances) {
        const st = models[inst].exit(handles[inst]);
        if (st > 1) { fail(inst, "exit-initialization-mode", st); return finish(); }
      }
      const buf = [];
      for (let k = 0; k <= n; k++) {
        const t = t0 + k * h;
        if (k > 0) {
          for (const inst of D.instances) {
            const st = models[inst].step(handles[inst], t0 + (k - 1) * h, h);
            if (st > 1 || st === 2) { fail(inst, "do-step", st); return finish(); }
          }
        }
        for (const op of plan) {
          const m = models[op.inst];
          if (op.read) {
            const st = m.get(handles[op.inst], op.type, op.vrs, buf);
            if (st > 1) { fail(op.inst, `get ${op.names.join(", ")}`, st); return finish(); }
            for (let i = 0; i < op.names.length; i++) values[op.names[i]] = buf[i];
          } else {
            const st = m.set(handles[op.inst], op.type, op.vrs, op.sources.map((x) => values[x]));
            if (st > 1) { fail(op.inst, `set ${op.vrs.join(", ")}`, st); return finish(); }
          }
        }
        cols.time[k] = t;
        for (const c of D.record) cols[c][k] = values[c];
        rows = k + 1;
      }
    } finally {
      for (const inst of Object.keys(handles)) models[inst].free(handles[inst]);
    }
    return finish();

    function finish() {
      for (const inst of D.instances) messages.push(...models[inst].messages);
      const out = { time: cols.time.slice(0, rows) };
      for (const c of D.record) out[c] = cols[c].slice(0, rows);
      out.status = status;
      out.message = failure;
      out.messages = messages;
      out.metrics = metrics(out, s, status === "ok");
      out.elapsed_ms = performance.now() - t0clock;
      return out;
    }
  }

  /* ------------------------------------------------------------ metrics
   * glider_cosim.runner.metrics.glide_metrics and runner.outcome.classify, on arrays. */
  const BAND_FRACTION = 0.02, BAND_FLOOR = 0.1 * Math.PI / 180;
  const MIN_HOLD_S = 10.0, HOLD_PERIODS = 3.0, MIN_WINDOW_S = 10.0, SUSTAINED = 0.01;
  const pymod = (a, b) => a - b * Math.floor(a / b);

  function crossings(t, e, hyst, jump) {
    const out = [];
    let last = -1, side = 0;
    for (let i = 0; i < e.length; i++) {
      let jumped = false;
      if (i > 0 && Math.sign(e[i]) !== Math.sign(e[i - 1]) && e[i - 1] !== 0) {
        if (Math.abs(e[i] - e[i - 1]) > jump) jumped = true;
        else last = i;
      }
      if (jumped) { side = 0; continue; }
      const s = e[i] > hyst ? 1 : e[i] < -hyst ? -1 : 0;
      if (s !== 0) {
        if (side !== 0 && s !== side && last >= 0) {
          const a = e[last - 1], b = e[last], ta = t[last - 1], tb = t[last];
          out.push(a !== b ? ta + (tb - ta) * a / (a - b) : tb);
        }
        side = s;
      }
    }
    return out;
  }

  function period(t, e, hyst, jump) {
    const c = crossings(t, e, hyst, jump);
    if (c.length < 3) return null;
    let best = -Infinity;
    for (let i = c.length > 3 ? 2 : 1; i < c.length; i++) best = Math.max(best, c[i] - c[i - 1]);
    return 2.0 * best;
  }

  function fitRate(x, y) {
    if (x.length < 2) return 0.0;
    const ly = y.map((v) => Math.log(Math.max(Math.abs(v), 1e-300)));
    let mx = 0, my = 0;
    for (let i = 0; i < x.length; i++) { mx += x[i]; my += ly[i]; }
    mx /= x.length; my /= x.length;
    let sxx = 0, sxy = 0;
    for (let i = 0; i < x.length; i++) { sxx += (x[i] - mx) ** 2; sxy += (x[i] - mx) * (ly[i] - my); }
    return sxx === 0 ? 0.0 : sxy / sxx;
  }

  function classify(t, e, band, per) {
    const width = Math.max(MIN_WINDOW_S, (t[t.length - 1] - t[0]) / 3.0);
    let i0 = t.findIndex((x) => x >= t[t.length - 1] - width);
    if (i0 < 0) i0 = t.length;
    let jump = Infinity;
    const tail = e.slice(i0);
    if (Math.max(...tail) - Math.min(...tail) > per) {
      const rate = (e[e.length - 1] - e[i0]) / (t[t.length - 1] - t[i0]) / per;
      return { status: "tumbling", period_s: rate ? 1 / Math.abs(rate) : null, rate_per_s: rate,
               window_s: [t[i0], t[t.length - 1]] };
    }
    e = e.map((x) => pymod(x + 0.5 * per, per) - 0.5 * per);
    jump = 0.5 * per;
    const pOsc = period(t, e, band, jump);
    const hold = Math.max(MIN_HOLD_S, HOLD_PERIODS * (pOsc || 0.0));
    let lastOut = -1;
    for (let i = 0; i < e.length; i++) if (Math.abs(e[i]) > band) lastOut = i;
    const tIn = lastOut < 0 ? t[0] : lastOut < e.length - 1 ? t[lastOut + 1] : null;
    const inBand = tIn === null ? null : t[t.length - 1] - tIn;
    if (inBand !== null && inBand >= hold) {
      return { status: "settled", settling_time_s: tIn - t[0], hold_s: hold, period_s: pOsc, in_band_s: inBand };
    }
    const tw = t.slice(i0), ew = e.slice(i0);
    const peak = Math.max(...ew.map(Math.abs));
    const c = peak > 0 ? crossings(tw, ew, 0.1 * peak, jump) : [];
    const window_s = [tw[0], tw[tw.length - 1]];
    if (c.length >= 4) {
      const idx = c.map((x) => { const j = tw.findIndex((y) => y >= x); return j < 0 ? tw.length : j; });
      const pkT = [], pkV = [];
      for (let j = 0; j + 1 < idx.length; j++) {
        let k = idx[j];
        for (let q = idx[j]; q < idx[j + 1]; q++) if (Math.abs(ew[q]) > Math.abs(ew[k])) k = q;
        pkT.push(tw[k]); pkV.push(Math.abs(ew[k]));
      }
      let mean = 0;
      for (let j = 1; j < c.length; j++) mean += c[j] - c[j - 1];
      const p = 2.0 * mean / (c.length - 1);
      const sigma = fitRate(pkT, pkV);
      const amp = pkV.reduce((a, b) => a + b, 0) / pkV.length;
      const perPeriod = Math.expm1(Math.abs(sigma) * p);
      const status = perPeriod < SUSTAINED ? "limit cycle" : sigma > 0 ? "diverging" : "not settled";
      return { status, period_s: p, amplitude: amp, rate_per_s: sigma, window_s, in_band_s: inBand, hold_s: hold };
    }
    const sigma = fitRate(tw, ew);
    const change = Math.expm1(sigma * (tw[tw.length - 1] - tw[0]));
    const away = Math.min(...ew.map(Math.abs)) > (1.0 + SUSTAINED) * Math.abs(e[0]);
    const status = change > SUSTAINED || away ? "diverging" : "not settled";
    const amp = ew.reduce((a, b) => a + Math.abs(b), 0) / ew.length;
    return { status, period_s: pOsc, amplitude: amp, rate_per_s: sigma, window_s, in_band_s: inBand, hold_s: hold };
  }

  /* the glide the loop should reach: the equilibrium, or the held tail's steady glide for
   * the open-loop law (runner.metrics.reference_glide) */
  const thetaGe = (s) => (s.law === "open loop" ? D.theta_ge.open : D.theta_ge.closed);

  function metrics(r, s, completed) {
    const t = r.time, th = r["plant.theta_g"], dc = r["controller.delta_cmd"];
    const ge = thetaGe(s);
    const out = { theta_ge_rad: ge, rows: t.length };
    if (t.length < 2) return Object.assign(out, { outcome: completed ? null : "stopped" });
    const h = t[1] - t[0];
    let effort = 0, maxCmd = 0;
    for (let i = 0; i < dc.length; i++) {
      if (i < dc.length - 1) effort += Math.abs(dc[i]);
      maxCmd = Math.max(maxCmd, Math.abs(dc[i]));
    }
    out.control_effort = effort * h;
    out.max_abs_delta_cmd_rad = maxCmd;
    const eTurns = th.map((x) => x - ge);
    const e = eTurns.map((x) => pymod(x + Math.PI, 2 * Math.PI) - Math.PI);
    const e0 = e[0];
    const band = Math.max(BAND_FRACTION * Math.abs(e0), BAND_FLOOR);
    out.settling_band_rad = band;
    if (Math.abs(e0) < 1e-12) Object.assign(out, { rise_time_s: 0, overshoot_rad: 0 });
    else {
      const k = e.findIndex((x) => Math.abs(x) <= 0.1 * Math.abs(e0));
      out.rise_time_s = k < 0 ? null : t[k] - t[0];
      out.overshoot_rad = Math.max(0, ...e.map((x) => -Math.sign(e0) * x));
    }
    out.settling_time_s = null;
    if (!completed) return Object.assign(out, { outcome: "stopped" });
    const o = classify(t.map((x) => x - t[0]), eTurns, band, 2 * Math.PI);
    out.outcome = o.status;
    out.settling_time_s = o.settling_time_s === undefined ? null : o.settling_time_s;
    out.outcome_period_s = o.period_s === undefined ? null : o.period_s;
    out.outcome_amplitude_rad = o.amplitude === undefined ? null : o.amplitude;
    out.outcome_rate_per_s = o.rate_per_s === undefined ? null : o.rate_per_s;
    return out;
  }

  function describe(m, r) {
    const deg = 180 / Math.PI;
    if (r.status === "stopped") return `stopped at ${r.time[r.time.length - 1].toFixed(2)} s (${r.message})`;
    if (r.status !== "ok") return `error: ${r.message}`;
    if (m.outcome === "settled") return `settled in ${m.settling_time_s.toFixed(2)} s`;
    if (m.outcome === "limit cycle") return `limit cycle: amplitude ${(m.outcome_amplitude_rad * deg).toFixed(2)} deg, period ${m.outcome_period_s.toFixed(2)} s`;
    if (m.outcome === "diverging") return `diverging: envelope grows at ${m.outcome_rate_per_s.toPrecision(3)} 1/s`;
    if (m.outcome === "tumbling") return "tumbling";
    return `not settled: |error| about ${(m.outcome_amplitude_rad * deg).toFixed(2)} deg`;
  }

  /* ------------------------------------------------------------ drawing */
  const PLOTS = [
    { id: "glide", title: "glide angle theta_g (deg)", series: [["plant.theta_g", "#1f77b4", "theta_g"]], deg: true, ref: true },
    { id: "pitch", title: "pitch theta and its estimate (deg)", series: [["plant.theta", "#1f77b4", "theta"], ["observer.theta_hat", "#d62728", "estimate"]], deg: true },
    { id: "tail", title: "tail angle delta and command (deg)", series: [["plant.delta", "#98df8a", "delta", 4], ["controller.delta_cmd", "#d62728", "command", 1.2, [5, 3]]], deg: true },
    { id: "speed", title: "speed V (m/s)", series: [["plant.V", "#9467bd", "V"]], deg: false },
  ];

  /** Round ticks covering [lo, hi]: about n steps of 1, 2 or 5 times a power of ten;
   * (values, decimals to print them with). */
  function niceTicks(lo, hi, n) {
    const raw = (hi - lo) / Math.max(n, 1);
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw * (1 - 1e-9));
    const decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
    const ticks = [];
    for (let i = Math.ceil(lo / step - 1e-9); i * step <= hi + step * 1e-9; i++) {
      ticks.push(Number((i * step).toFixed(decimals)) + 0);  // + 0: no "-0"
    }
    return { ticks, decimals };
  }

  function draw(canvas, plot, r, ge) {
    const ctx = canvas.getContext("2d");
    const W = canvas.width, H = canvas.height, L = 56, R = 10, T = 22, B = 26;
    ctx.clearRect(0, 0, W, H);
    const t = r.time, k = plot.deg ? 180 / Math.PI : 1;
    let lo = Infinity, hi = -Infinity;
    for (const [name] of plot.series) for (const v of r[name] || []) { const x = v * k; if (x < lo) lo = x; if (x > hi) hi = x; }
    if (plot.ref) { lo = Math.min(lo, ge * k); hi = Math.max(hi, ge * k); }
    if (!(hi > lo)) { lo -= 1; hi += 1; }
    const pad = 0.05 * (hi - lo); lo -= pad; hi += pad;
    const tEnd = t.length ? Math.max(t[t.length - 1], D.step) : 1;
    const X = (x) => L + (W - L - R) * x / tEnd, Y = (y) => T + (H - T - B) * (hi - y) / (hi - lo);
    ctx.strokeStyle = "#ccc"; ctx.fillStyle = "#333"; ctx.font = "11px sans-serif"; ctx.lineWidth = 1;
    const yt = niceTicks(lo, hi, 5), xt = niceTicks(0, tEnd, 4);
    const shown = { y: [], x: [] };
    for (const y of yt.ticks) {
      ctx.beginPath(); ctx.moveTo(L, Y(y)); ctx.lineTo(W - R, Y(y)); ctx.stroke();
      shown.y.push(y.toFixed(yt.decimals)); ctx.fillText(shown.y[shown.y.length - 1], 4, Y(y) + 4);
    }
    for (const x of xt.ticks) {
      shown.x.push(`${x.toFixed(xt.decimals)} s`);
      ctx.fillText(shown.x[shown.x.length - 1], Math.min(X(x) - 10, W - R - 30), H - 8);
    }
    if (window.glider) (window.glider.ticks = window.glider.ticks || {})[plot.id] = shown;
    ctx.fillText(plot.title, L, 14);
    if (plot.ref) {
      ctx.setLineDash([4, 4]); ctx.strokeStyle = "#888";
      ctx.beginPath(); ctx.moveTo(L, Y(ge * k)); ctx.lineTo(W - R, Y(ge * k)); ctx.stroke();
      ctx.setLineDash([]);
    }
    let lx = W - R - 150;
    for (const [name, color, label, width, dash] of plot.series) {
      const v = r[name] || [];
      ctx.strokeStyle = color; ctx.lineWidth = width || 1.5; ctx.setLineDash(dash || []); ctx.beginPath();
      const stride = Math.max(1, Math.floor(v.length / (2 * (W - L - R))));
      for (let i = 0; i < v.length; i += stride) { const px = X(t[i]), py = Y(v[i] * k); if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py); }
      ctx.stroke(); ctx.setLineDash([]);
      ctx.fillStyle = color; ctx.fillRect(lx, 8, 12, 3); ctx.fillStyle = "#333"; ctx.fillText(label, lx + 16, 13); lx += 75;
    }
  }

  /* ------------------------------------------------------------ the page */
  const FIELDS = [
    ["law", "law", null], ["K_c", "K_c (passivity law; it divides by K_c: larger is gentler)", 1],
    ["K_P", "K_P (P and PI laws)", 1], ["K_I", "K_I (1/s, PI law)", 1],
    ["noise_std", "pitch noise (deg)", 180 / Math.PI], ["tau_servo", "servo time constant (s)", 1],
    ["f_cutoff", "filter cutoff (Hz)", 1], ["theta_g_0", "initial glide angle (deg)", 180 / Math.PI],
    ["coupling", "coupling", null], ["stop_time", "stop time (s)", 1],
  ];
  const RANGES = { K_c: [0.5, 30, 0.1], K_P: [0, 5, 0.05], K_I: [0, 2, 0.01], noise_std: [0, 2, 0.01],
    tau_servo: [0, 1, 0.005], f_cutoff: [0.5, 24, 0.1], theta_g_0: [-80, -5, 0.5], stop_time: [5, 200, 1] };

  /** The gains each law uses: the others' sliders are disabled under it. */
  const USES = { "open loop": [], passivity: ["K_c"], P: ["K_P"], PI: ["K_P", "K_I"] };
  const GAINS = ["K_c", "K_P", "K_I"];

  function enableGains() {
    const used = USES[document.getElementById("f-law").value] || [];
    for (const key of GAINS) {
      const el = document.getElementById("f-" + key), on = used.includes(key);
      el.disabled = !on;
      el.parentElement.style.opacity = on ? "1" : "0.45";
      el.title = on ? "" : "not used by this law";
    }
  }

  function settingsFromForm() {
    const s = {};
    for (const [key, , scale] of FIELDS) {
      const el = document.getElementById("f-" + key);
      if (scale === null) s[key] = el.value;
      else s[key] = key === "noise_std" || key === "theta_g_0" ? Number(el.value) * (Math.PI / 180) : Number(el.value);
    }
    return s;
  }

  function rerun() {
    enableGains();
    const s = settingsFromForm();
    for (const [key, , scale] of FIELDS) {
      const out = document.getElementById("v-" + key);
      if (out) out.textContent = scale === null ? "" : document.getElementById("f-" + key).value;
    }
    const start = performance.now();
    const r = simulate(s);
    const simulated = performance.now();
    for (const p of PLOTS) draw(document.getElementById("c-" + p.id), p, r, r.metrics.theta_ge_rad);
    const drawn = performance.now();
    const m = r.metrics, deg = 180 / Math.PI;
    const f = (x, d) => (x === null || x === undefined ? "n/a" : x.toFixed(d));
    document.getElementById("metrics").textContent =
      `outcome: ${describe(m, r)} | settling ${f(m.settling_time_s, 2)} s | overshoot ` +
      `${f(m.overshoot_rad === undefined ? null : m.overshoot_rad * deg, 3)} deg | rise ` +
      `${f(m.rise_time_s, 2)} s | effort ${f(m.control_effort, 3)} rad s`;
    const total = drawn - start;
    document.getElementById("timing").textContent =
      `${r.time.length - 1} macro steps simulated in ${(simulated - start).toFixed(1)} ms and drawn in ` +
      `${(drawn - simulated).toFixed(1)} ms: ${total.toFixed(1)} ms (target 50 ms)`;
    window.glider.last = { simulate_ms: simulated - start, draw_ms: drawn - simulated, total_ms: total, steps: r.time.length - 1 };
  }

  function buildForm() {
    const form = document.getElementById("form");
    for (const [key, label, scale] of FIELDS) {
      const row = document.createElement("label");
      row.textContent = label + " ";
      let el;
      if (key === "law" || key === "coupling") {
        el = document.createElement("select");
        for (const o of key === "law" ? Object.keys(LAWS) : Object.keys(D.plans)) {
          const opt = document.createElement("option"); opt.value = opt.textContent = o; el.appendChild(opt);
        }
        el.value = defaults[key];
      } else {
        el = document.createElement("input");
        el.type = "range";
        [el.min, el.max, el.step] = RANGES[key];
        el.value = String(Math.round(defaults[key] * scale / el.step) * el.step);
        const out = document.createElement("output"); out.id = "v-" + key;
        row.appendChild(el); row.appendChild(out);
      }
      el.id = "f-" + key;
      el.addEventListener("input", rerun);
      if (!row.contains(el)) row.appendChild(el);
      form.appendChild(row);
    }
  }

  const models = {};
  const ready = (async () => {
    for (const inst of D.instances) models[inst] = await Model.load(D.modules[D.module_of[inst]], []);
  })();
  window.glider = { ready, simulate, defaults, data: { instances: D.instances, record: D.record, scenario: D.scenario } };
  window.addEventListener("load", () => {
    // one run first, not shown: the browser compiles the script and the modules' hot code
    // on it, so the timing printed is that of a change (the first run takes 2-4x longer)
    ready.then(() => { simulate({}); buildForm(); rerun(); }).catch((err) => console.error(String(err)));
  });
})();
