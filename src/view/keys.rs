//! The window's keys as data: which key (with or without Shift) gives which [`Action`], the
//! same action the script line of [`Action::verb`] gives, so a key press and a script line
//! share one path into [`super::Viewer::apply`]. The window translates winit's key into a
//! [`Key`]; [`key_action`] needs no window, so every binding is tested without one.

use super::script::Action;
use super::{MODEL_CYCLE, Viewer};
use crate::job::ModelChoice;
use crate::prescription::StopShape;
use std::path::PathBuf;

/// A key the window reads: a character as the keyboard layout types it (lower case), an arrow
/// or Escape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    Char(char),
    Left,
    Right,
    Up,
    Down,
    Escape,
}

/// One key binding: the key, whether Shift is held, what the help says it does, and the
/// script verb of the action it gives.
#[derive(Clone, Copy, Debug)]
pub struct Binding {
    pub key: Key,
    pub shift: bool,
    pub does: &'static str,
    pub verb: &'static str,
}

const fn bind(key: Key, shift: bool, verb: &'static str, does: &'static str) -> Binding {
    Binding {
        key,
        shift,
        does,
        verb,
    }
}

/// Every key the window answers, in the order the help lists them.
pub const BINDINGS: &[Binding] = &[
    bind(Key::Char('['), false, "focus", "focus a quarter nearer"),
    bind(Key::Char(']'), false, "focus", "focus a quarter farther"),
    bind(Key::Char('f'), false, "fnumber", "close one third stop"),
    bind(Key::Char('f'), true, "fnumber", "open one third stop"),
    bind(Key::Char('m'), false, "model", "next model"),
    bind(Key::Char('c'), false, "chromatic", "chromatic on/off"),
    bind(Key::Char('s'), false, "split", "split view on/off"),
    bind(Key::Char('e'), false, "overlay", "error overlay on/off"),
    bind(Key::Left, false, "shift", "shift the sensor 0.5 mm left"),
    bind(Key::Right, false, "shift", "shift the sensor 0.5 mm right"),
    bind(Key::Up, false, "shift", "shift the sensor 0.5 mm up"),
    bind(Key::Down, false, "shift", "shift the sensor 0.5 mm down"),
    bind(Key::Left, true, "tilt", "tilt the sensor 0.5 degrees left"),
    bind(
        Key::Right,
        true,
        "tilt",
        "tilt the sensor 0.5 degrees right",
    ),
    bind(Key::Up, true, "tilt", "tilt the sensor 0.5 degrees up"),
    bind(Key::Down, true, "tilt", "tilt the sensor 0.5 degrees down"),
    bind(Key::Char(','), false, "exposure", "exposure -1/3 EV"),
    bind(Key::Char('.'), false, "exposure", "exposure +1/3 EV"),
    bind(Key::Char('w'), false, "sensor", "sensor a quarter wider"),
    bind(Key::Char('w'), true, "sensor", "sensor a quarter narrower"),
    bind(
        Key::Char('z'),
        false,
        "zone",
        "tint the zone of focus on/off",
    ),
    bind(
        Key::Char('o'),
        false,
        "orbit",
        "orbit 5 degrees right (mesh scenes)",
    ),
    bind(Key::Char('o'), true, "orbit", "orbit 5 degrees left"),
    bind(Key::Char('i'), false, "orbit", "orbit 5 degrees up"),
    bind(Key::Char('i'), true, "orbit", "orbit 5 degrees down"),
    bind(
        Key::Char('b'),
        false,
        "blades",
        "one aperture blade more (round after 9)",
    ),
    bind(Key::Char('b'), true, "blades", "turn the blades 10 degrees"),
    bind(
        Key::Char('k'),
        false,
        "zoom",
        "next zoom position (zoom lenses)",
    ),
    bind(Key::Char('k'), true, "zoom", "previous zoom position"),
    bind(Key::Char('l'), false, "lens", "next bundled lens"),
    bind(
        Key::Char('+'),
        false,
        "spp-per-frame",
        "double samples per frame",
    ),
    bind(
        Key::Char('-'),
        false,
        "spp-per-frame",
        "halve samples per frame",
    ),
    bind(
        Key::Char('p'),
        false,
        "screenshot",
        "screenshot (lensbake-view-N.png)",
    ),
    bind(Key::Char('q'), false, "quit", "quit"),
    bind(Key::Escape, false, "quit", "quit"),
];

/// How a key is written in the help: `F`, `Shift+F`, `Left`, `Esc`.
pub fn key_name(key: Key, shift: bool) -> String {
    let name = match key {
        Key::Char(c) => c.to_uppercase().to_string(),
        Key::Left => "Left".into(),
        Key::Right => "Right".into(),
        Key::Up => "Up".into(),
        Key::Down => "Down".into(),
        Key::Escape => "Esc".into(),
    };
    if shift { format!("Shift+{name}") } else { name }
}

/// The key help, one `key: what it does` a binding, then the mouse and dropped files: what
/// `lensbake view --help` prints and the guide's key table lists.
pub fn keys_help() -> String {
    let mut parts = vec![
        "click: focus there".to_string(),
        "Shift+click: add a focal-surface point there".to_string(),
    ];
    parts.extend(
        BINDINGS
            .iter()
            .map(|b| format!("{}: {}", key_name(b.key, b.shift), b.does)),
    );
    parts.push("drop a lens, glTF or EXR file: load it".to_string());
    parts.join("; ")
}

/// The action `key` (with Shift held or not) gives on `viewer` as it stands; `screenshot` numbers
/// the file a screenshot key writes. None for a key without a binding.
pub fn key_action(viewer: &Viewer, key: Key, shift: bool, screenshot: u32) -> Option<Action> {
    let job = viewer.job();
    let third_stop = 2f64.powf(1.0 / 6.0);
    let current_f = job
        .lens
        .first_order(job.f_number)
        .map(|(_, f)| f)
        .unwrap_or(2.8);
    let [sx, sy] = job.shift_mm;
    let [tx, ty] = job.tilt_deg;
    let nudge = |dx: f64, dy: f64| -> Action {
        if shift {
            Action::Tilt([tx + dx, ty + dy])
        } else {
            Action::Shift([sx + dx, sy + dy])
        }
    };
    Some(match key {
        Key::Left => nudge(-0.5, 0.0),
        Key::Right => nudge(0.5, 0.0),
        Key::Up => nudge(0.0, 0.5),
        Key::Down => nudge(0.0, -0.5),
        Key::Escape => Action::Quit,
        Key::Char(c) => match c.to_ascii_lowercase() {
            'f' if shift => Action::FNumber(current_f / third_stop),
            'f' => Action::FNumber(current_f * third_stop),
            'm' => {
                let shown = match job.model {
                    ModelChoice::Model(kind) => kind,
                    ModelChoice::ErrorBudgetPx(_) => viewer.shown_model(),
                };
                let at = MODEL_CYCLE.iter().position(|&k| k == shown).unwrap_or(0);
                Action::Model(MODEL_CYCLE[(at + 1) % MODEL_CYCLE.len()])
            }
            '[' | ']' => {
                // A quarter nearer or farther; from a focus at infinity, 100 m in.
                let focus = viewer.focus_distance_mm().flatten().unwrap_or(100_000.0);
                Action::Focus(if c == '[' { focus / 1.25 } else { focus * 1.25 })
            }
            ',' | '.' => {
                let step = if c == ',' { -1.0 } else { 1.0 } / 3.0;
                Action::Exposure(viewer.exposure_ev() + step)
            }
            'w' => {
                let width = viewer.camera().film.width_mm;
                Action::SensorWidth(if shift { width / 1.25 } else { width * 1.25 })
            }
            'z' => Action::ZoneOverlay(!viewer.zone()),
            'o' | 'i' => {
                let [yaw, pitch] = job.orbit.map_or([0.0, 0.0], |o| o.angles_deg);
                let step = if shift { -5.0 } else { 5.0 };
                Action::Orbit(if c.eq_ignore_ascii_case(&'o') {
                    [yaw + step, pitch]
                } else {
                    [yaw, pitch + step]
                })
            }
            'b' => {
                let blades = match job.lens.real().and_then(|lens| lens.stop_shape()) {
                    Some(&StopShape::Blades {
                        count,
                        rotation_deg,
                        blade_curvature,
                    }) => Some((count, rotation_deg, blade_curvature)),
                    _ => None,
                };
                Action::Blades(match (blades, shift) {
                    (Some((count, rotation, curvature)), true) => {
                        Some((count, rotation + 10.0, curvature))
                    }
                    (Some((count, ..)), false) if count >= 9 => None,
                    (Some((count, rotation, curvature)), false) => {
                        Some((count + 1, rotation, curvature))
                    }
                    (None, _) => Some((5, 0.0, 0.0)),
                })
            }
            'k' => {
                // Round the positions: after the last comes the first.
                let (position, count) = viewer.zoom_position();
                let next = if shift {
                    (position + count - 2) % count + 1
                } else {
                    position % count + 1
                };
                Action::Zoom(next)
            }
            'c' => Action::Chromatic(viewer.camera().chromatic.is_none()),
            's' => Action::Split(!viewer.split()),
            'e' => Action::ErrorOverlay(!viewer.overlay()),
            'l' => viewer.next_bundled_lens(),
            '+' | '=' => Action::SppPerFrame(viewer.spp_per_frame().saturating_mul(2)),
            '-' => Action::SppPerFrame((viewer.spp_per_frame() / 2).max(1)),
            'p' => Action::Screenshot(PathBuf::from(format!("lensbake-view-{screenshot}.png"))),
            'q' => Action::Quit,
            _ => return None,
        },
    })
}
