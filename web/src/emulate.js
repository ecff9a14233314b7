// Desktop emulation (loaded only for ?emulate=quest3 or ?emulate=quest2): Meta's IWER runtime
// replaces navigator.xr with an emulated headset whose hands are tracked, and its dev UI lets a
// person drive the hands with mouse and keyboard. Tests replay recorded hands through IWER's
// ActionPlayer (see python/mimicrete/testing/page_driver.py, which builds the recordings).
import { XRDevice, metaQuest2, metaQuest3 } from 'iwer';
import { DevUI } from '@iwer/devui';

export const DEVICES = { quest3: metaQuest3, quest2: metaQuest2 };

/** Install the emulated runtime before anything asks navigator.xr. Returns the XRDevice. */
export function installEmulator(kind, { devui = true } = {}) {
  const device = new XRDevice(DEVICES[kind] ?? metaQuest3);
  // Hands, not controllers, are the device's inputs (WebXR hand-tracking inputs with XRHand).
  device.primaryInputMode = 'hand';
  // forceInstall: replace navigator.xr even where the browser has a (non-functional) native one,
  // as headless Chromium does.
  device.installRuntime({ forceInstall: true });
  if (devui) device.installDevUI(DevUI);
  return device;
}

/**
 * Play a recording (IWER's ActionRecorder format, built by page_driver.py) from the next XR frame on.
 *
 * IWER facts this relies on (iwer 2.5.0, lib/action/ActionPlayer.js and device/XRDevice.js):
 * - while a player is `playing`, XRDevice.inputSources are the player's, and at the start of every
 *   XR frame (before the page's callbacks) the device calls `player.playFrame()`;
 * - each recorded hand joint is an XRJointSpace whose parent is the source's target-ray space,
 *   whose parent is the `refSpace` given here: with the target ray recorded as the identity,
 *   fillPoses(joints, refSpace) returns the recorded joint poses (as float32 matrices);
 * - `playFrame()` advances a playback clock by wall-clock time × playbackRate and sets each joint
 *   to lerp(position) / slerp(orientation) between the two recorded frames around that clock; an
 *   input source is present in a frame iff it is present in the *later* of the two frames.
 *
 * mode 'interpolate': exactly IWER's own playback (above).
 * mode 'exact': sample-and-hold. The recording holds every log record twice (A_i at t_i, B_i at
 *   t_i + δ); we replace this player's playFrame so that each XR frame seeks to the A_i of the
 *   latest record at or before the elapsed time and applies it with interpolation factor 0, the
 *   deterministic path IWER's stepFrames uses. The next frame is B_i, an identical copy, so poses
 *   and presence are exactly record i's.
 */
export class Replay {
  constructor(device, refSpace, recording, mode = 'exact') {
    if (mode !== 'exact' && mode !== 'interpolate') throw new Error(`replay mode ${mode}`);
    this.mode = mode;
    this.player = device.createActionPlayer(refSpace, recording);
    this.durationMs = recording.mimicrete?.duration_ms ?? this.player.duration;
    this.index = -1;
    if (mode === 'exact') {
      if (recording.mimicrete?.mode !== 'exact') {
        throw new Error("mode 'exact' needs a recording built with mode='exact' (paired frames)");
      }
      const times = recording.frames.filter((_, i) => i % 2 === 0).map((f) => f[0]);
      const player = this.player;
      this.player.playFrame = () => {
        const elapsed = (performance.now() - this.startMs) * player.playbackRate;
        let lo = 0;
        let hi = times.length - 1;
        while (lo < hi) { // last i with times[i] <= elapsed (times[0] is 0)
          const mid = (lo + hi + 1) >> 1;
          if (times[mid] <= elapsed) lo = mid; else hi = mid - 1;
        }
        this.index = lo;
        player.seek(times[lo]);
        player.applyFrameAtPointer(0);
      };
    }
  }

  start() {
    this.startMs = performance.now();
    this.player.play();
  }

  stop() {
    this.player.stop();
  }

  /** What the frame being drawn shows: the playback clock (ms from the start) and, when exact,
   * the record index. Call inside the XR frame callback. */
  sample() {
    return { timeMs: this.player.currentTime, index: this.mode === 'exact' ? this.index : null };
  }

  get done() {
    return this.player.currentTime >= this.durationMs;
  }
}
