// The gesture mode's panel: the classes to record (each with what it commands and a gesture to
// try), a bar per class filling to its target, Record / Redo per class, Pause and Train, and the
// last training's result (held-out accuracy, 5-fold CV accuracy, the confusion matrix). Drawn
// from the server's `gestures` messages only (docs/formats.md §3); no three.js.

const pct = (x) => (Number.isFinite(x) ? `${(100 * x).toFixed(1)} %` : '–');

function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (k === 'dataset') Object.assign(e.dataset, v);
    else if (k === 'style') e.setAttribute('style', v);
    else e[k] = v;
  }
  e.append(...children);
  return e;
}

/** One line saying what to do now. */
export function gesturePrompt(g) {
  if (!g) return '';
  const p = (c) => g.prompts?.[c];
  if (g.training) return 'training the SVM on your samples (5-fold CV)…';
  if (g.current) {
    const n = g.counts[g.current] ?? 0;
    return `hold ${g.current}: ${p(g.current)?.meaning ?? ''} (try ${p(g.current)?.try ?? 'any shape'}); `
      + `move and turn your hand around the workspace · ${n}/${g.target}`;
  }
  if (g.next) {
    return `next: ${g.next} (${p(g.next)?.meaning ?? ''}; try ${p(g.next)?.try ?? 'any shape'}): `
      + 'press Record, or pinch with the left hand for 1 s';
  }
  if (g.error) return g.error;
  if (g.report) return 'your model drives now: leave the gesture mode (or pinch left 1 s) to record demos';
  return 'every class recorded: press Train';
}

/** The result line: held-out accuracy, CV accuracy, sample counts. */
export function gestureResult(r) {
  if (!r) return '';
  return `held-out accuracy ${pct(r.test_accuracy)} on ${r.n_test} samples · `
    + `5-fold CV ${pct(r.cv_accuracy)} on ${r.n_train}`;
}

export class GesturePanel {
  /**
   * The elements are made once per set of classes and then updated in place (samples arrive at
   * up to 20 a second: a button rebuilt under the pointer would lose its click).
   * @param {HTMLElement} root  the panel (hidden outside the gesture mode)
   * @param {(action: string, opts?: object) => void} send  sends a `gestures` request
   */
  constructor(root, send) {
    this.root = root;
    this.send = send;
    this.status = null;
    this.key = null; // task + classes the elements were made for
    this.reportKey = null;
    this.rows = {};
  }

  build(g) {
    this.rows = {};
    const rows = g.classes.map((c) => {
      const button = el('button', { id: `gest-record-${c}`, textContent: 'Record' });
      button.addEventListener('click', () => this.send('record', { cls: c }));
      const fill = el('span', { className: 'gest-fill' });
      const count = el('span', { className: 'gest-count' });
      const row = el('div', { className: 'gest-row', dataset: { cls: c } },
        el('span', { className: 'gest-name', textContent: c, title: g.prompts?.[c]?.meaning ?? '' }),
        el('span', { className: 'gest-bar' }, fill),
        count,
        button);
      this.rows[c] = { row, fill, count, button };
      return row;
    });
    this.pause = el('button', { id: 'gest-pause', textContent: 'Pause' });
    this.pause.addEventListener('click', () => this.send('pause'));
    this.train = el('button', {
      id: 'gest-train',
      textContent: 'Train',
      title: 'write the labelled CSV, fit the SVM (5-fold CV), save and use it',
    });
    this.train.addEventListener('click', () => this.send('train'));
    this.prompt = el('div', { id: 'gest-prompt' });
    this.result = el('div', { id: 'gest-result' });
    this.error = el('div', { id: 'gest-error', className: 'warn' });
    this.root.replaceChildren(
      el('div', { className: 'gest-title', textContent: `Your gestures · ${g.task}` }),
      this.prompt,
      ...rows,
      el('div', { className: 'gest-actions' }, this.pause, this.train),
      this.result,
      this.error,
    );
    this.reportKey = null;
  }

  update(g) {
    this.status = g;
    this.root.hidden = !g?.active;
    if (!g?.active) return;
    const key = JSON.stringify([g.task, g.classes]);
    if (key !== this.key) {
      this.build(g);
      this.key = key;
    }
    this.prompt.textContent = gesturePrompt(g);
    for (const c of g.classes) {
      const { row, fill, count, button } = this.rows[c];
      const n = g.counts[c] ?? 0;
      const recording = g.current === c;
      row.classList.toggle('recording', recording);
      fill.style.width = `${(100 * Math.min(1, n / Math.max(1, g.target))).toFixed(1)}%`;
      count.textContent = `${n}/${g.target}`;
      button.textContent = recording ? 'Recording' : n > 0 ? 'Redo' : 'Record';
      button.disabled = g.training || recording;
      button.title = n > 0 ? 'drop these samples and record the class again' : 'record this class';
    }
    this.pause.disabled = !g.current;
    this.train.disabled = g.training;
    this.train.textContent = g.training ? 'Training…' : 'Train';
    const reportKey = JSON.stringify(g.report);
    if (reportKey !== this.reportKey) {
      this.reportKey = reportKey;
      const r = g.report;
      this.result.replaceChildren(...(r ? [
        el('div', { id: 'gest-accuracy', textContent: gestureResult(r) }),
        confusionTable(r),
        el('div', { className: 'gest-file', textContent: `saved ${r.model}` }),
      ] : []));
    }
    this.error.textContent = g.error ?? '';
    this.error.hidden = !g.error;
  }
}

/** The confusion matrix of the held-out samples: rows truth, columns prediction. */
export function confusionTable(r) {
  const head = el('tr', {}, el('th', { textContent: 'truth \\ read as' }),
    ...r.classes.map((c) => el('th', { textContent: c })));
  const body = r.confusion.map((row, i) => el('tr', {},
    el('th', { textContent: r.classes[i] }),
    ...row.map((n, j) => el('td', {
      textContent: String(n),
      className: i === j ? 'diag' : n > 0 ? 'miss' : '',
    }))));
  return el('table', { id: 'gest-confusion' }, head, ...body);
}
