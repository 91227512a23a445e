//! Keys of the window and what they do. The mapping from keys to [`Action`]s and the effect of
//! the settings actions on a [`Session`] live here, apart from the window, so they are tested
//! without one.
//!
//! | key | action |
//! |---|---|
//! | W A S D | move forward / left / back / right |
//! | Q E | move down / up |
//! | mouse drag (left button) | look around |
//! | wheel | movement speed ×/÷ 1.25 |
//! | R | reset the camera (a jump: chains restart) |
//! | 1 … 9, Tab | VPL sampler by number / next (sir, sir-cdf, bir, and mh, mtmh when built in) |
//! | = / − (also keypad + / −) | VPLs per frame ×2 / ÷2 |
//! | I | interleave tile 1×1 → 2×2 → 4×4 → 8×8 → 16×16 |
//! | C | clamp on / off; `.` / `,` clamp bound ×10 / ÷10 |
//! | B | clamp compensation on / off (its time shows in the HUD as COMP) |
//! | F | discontinuity filter on / off |
//! | K | chain reuse / fresh chains every frame |
//! | P or F12 | screenshot (EXR + PNG) |
//! | [ / ] | exposure −1 / +1 stop (filmic and linear tone mapping; the HUD shows it) |
//! | H | HUD on / off; F1 key help |
//! | Esc | quit |

use clap::ValueEnum;
use winit::keyboard::KeyCode;

use super::session::Session;
use super::session::sampler_name;
use crate::options::VplSamplerArg;

/// Interleave tiles that I cycles through.
pub const INTERLEAVE_STEPS: [u32; 5] = [1, 2, 4, 8, 16];
/// Largest VPL count the keys reach.
pub const MAX_VPLS: usize = 1 << 20;

/// Something a key asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Use the i-th sampler of `VplSamplerArg::value_variants()`.
    SelectSampler(usize),
    /// Use the next sampler.
    NextSampler,
    /// Double the VPLs per frame.
    MoreVpls,
    /// Halve the VPLs per frame.
    FewerVpls,
    /// Next interleave tile.
    NextInterleave,
    /// Clamp on / off.
    ToggleClamp,
    /// Clamp bound ×10.
    ClampUp,
    /// Clamp bound ÷10.
    ClampDown,
    /// Clamp compensation on / off.
    ToggleCompensation,
    /// Discontinuity filter on / off.
    ToggleFilter,
    /// Chain reuse / fresh chains.
    ToggleChains,
    /// Screenshot.
    Screenshot,
    /// Exposure one stop down.
    ExposureDown,
    /// Exposure one stop up.
    ExposureUp,
    /// HUD on / off.
    ToggleHud,
    /// Key help on / off.
    ToggleHelp,
    /// Camera back to the start.
    Reset,
    /// Close the window.
    Quit,
}

/// The action of a key press, if any (movement keys are held, not pressed: see the window).
pub fn action_for(key: KeyCode) -> Option<Action> {
    use KeyCode::*;
    Some(match key {
        Digit1 | Digit2 | Digit3 | Digit4 | Digit5 | Digit6 | Digit7 | Digit8 | Digit9 => {
            let digits = [Digit1, Digit2, Digit3, Digit4, Digit5, Digit6, Digit7, Digit8, Digit9];
            Action::SelectSampler(digits.iter().position(|d| *d == key).unwrap_or(0))
        }
        Tab => Action::NextSampler,
        Equal | NumpadAdd | PageUp => Action::MoreVpls,
        Minus | NumpadSubtract | PageDown => Action::FewerVpls,
        KeyI => Action::NextInterleave,
        KeyC => Action::ToggleClamp,
        Period => Action::ClampUp,
        Comma => Action::ClampDown,
        KeyB => Action::ToggleCompensation,
        KeyF => Action::ToggleFilter,
        KeyK => Action::ToggleChains,
        KeyP | F12 => Action::Screenshot,
        BracketLeft => Action::ExposureDown,
        BracketRight => Action::ExposureUp,
        KeyH => Action::ToggleHud,
        F1 => Action::ToggleHelp,
        KeyR => Action::Reset,
        Escape => Action::Quit,
        _ => return None,
    })
}

/// One line per key, for the help overlay.
pub const HELP: [&str; 14] = [
    "WASD/QE MOVE   DRAG LOOK   WHEEL SPEED",
    "R RESET CAMERA",
    "1-9 / TAB  VPL SAMPLER",
    "= / -  VPLS X2 / /2",
    "I  INTERLEAVE TILE",
    "C  CLAMP ON/OFF   . / ,  CLAMP X10 / /10",
    "B  CLAMP COMPENSATION ON/OFF",
    "F  FILTER ON/OFF",
    "K  CHAIN REUSE / FRESH",
    "P  SCREENSHOT (EXR + PNG)",
    "[ / ]  EXPOSURE -1 / +1 STOP",
    "H  HUD   F1 HELP",
    "ESC  QUIT",
    "",
];

/// What the settings keys remember while a setting is off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlState {
    /// The clamp bound C turns back on.
    pub clamp_bound: f32,
    /// The filter thresholds F turns back on.
    pub filter: (f32, f32),
}

impl ControlState {
    /// Remembers the starting settings (clamp 300 and filter 20° / 5 % when they start off).
    pub fn new(frame: &crate::frame::FrameSettings) -> Self {
        ControlState {
            clamp_bound: if frame.clamp > 0.0 { frame.clamp } else { 300.0 },
            filter: frame.filter.unwrap_or((20.0, 0.05)),
        }
    }
}

/// Applies a settings action to the session; returns a message for the HUD, or `None` for
/// actions that are not about settings (the window handles those).
pub fn apply(action: Action, session: &mut Session, state: &mut ControlState) -> Option<String> {
    let mut f = session.settings().frame;
    let msg = match action {
        Action::SelectSampler(_) | Action::NextSampler => {
            let all = VplSamplerArg::value_variants();
            let i = match action {
                Action::SelectSampler(i) => i,
                _ => (all.iter().position(|v| *v == session.settings().sampler).unwrap_or(0) + 1) % all.len(),
            };
            let arg = *all.get(i)?;
            session.set_sampler(arg);
            return Some(format!("sampler {}", sampler_name(arg)));
        }
        Action::MoreVpls | Action::FewerVpls => {
            f.vpls = if action == Action::MoreVpls { f.vpls * 2 } else { f.vpls / 2 }.clamp(1, MAX_VPLS);
            format!("{} VPLs", f.vpls)
        }
        Action::NextInterleave => {
            let i = INTERLEAVE_STEPS.iter().position(|&s| (s, s) == f.interleave).map_or(0, |i| i + 1);
            let s = INTERLEAVE_STEPS[i % INTERLEAVE_STEPS.len()];
            f.interleave = (s, s);
            format!("interleave {s}x{s}")
        }
        Action::ToggleClamp => {
            if f.clamp > 0.0 {
                state.clamp_bound = f.clamp;
                f.clamp = 0.0;
                "clamp off".into()
            } else {
                f.clamp = state.clamp_bound;
                format!("clamp {}", f.clamp)
            }
        }
        Action::ClampUp | Action::ClampDown => {
            let k = if action == Action::ClampUp { 10.0 } else { 0.1 };
            let base = if f.clamp > 0.0 { f.clamp } else { state.clamp_bound };
            f.clamp = (base * k).clamp(1e-3, 1e12);
            state.clamp_bound = f.clamp;
            format!("clamp {}", f.clamp)
        }
        Action::ToggleCompensation => {
            f.compensate = !f.compensate;
            format!("clamp compensation {}", if f.compensate { "on" } else { "off" })
        }
        Action::ToggleFilter => {
            f.filter = match f.filter {
                Some(t) => {
                    state.filter = t;
                    None
                }
                None => Some(state.filter),
            };
            format!("filter {}", if f.filter.is_some() { "on" } else { "off" })
        }
        Action::ToggleChains => {
            let fresh = !session.settings().fresh_chains;
            session.set_fresh_chains(fresh);
            return Some(if fresh { "fresh chains every frame".into() } else { "chain reuse".into() });
        }
        _ => return None,
    };
    session.set_frame_settings(f);
    Some(msg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Accel;
    use crate::load::builtin;
    use crate::scene::{CameraSettings, Scene};
    use crate::view::session::SessionSettings;

    fn session() -> Session {
        let scene = Scene::from_desc(builtin::cornell(), &CameraSettings::default()).unwrap();
        let accel = Accel::build(&scene.mesh);
        let camera = scene.camera.clone().with_resolution(8, 8);
        let settings = SessionSettings { sampler: VplSamplerArg::Sir, max_depth: 8, ..Default::default() };
        Session::new(scene, accel, camera, settings)
    }

    #[test]
    fn every_sampler_is_reachable_by_number_and_by_cycling() {
        let mut s = session();
        let mut st = ControlState::new(&s.settings().frame);
        let all = VplSamplerArg::value_variants();
        for (i, v) in all.iter().enumerate() {
            assert_eq!(apply(Action::SelectSampler(i), &mut s, &mut st), Some(format!("sampler {}", sampler_name(*v))));
            assert_eq!(s.settings().sampler, *v);
        }
        apply(Action::NextSampler, &mut s, &mut st);
        assert_eq!(s.settings().sampler, all[0]);
        assert_eq!(apply(Action::SelectSampler(all.len()), &mut s, &mut st), None);
        assert_eq!(action_for(KeyCode::Digit3), Some(Action::SelectSampler(2)));
    }

    #[test]
    fn settings_keys_change_the_frame_settings_and_toggle_back() {
        let mut s = session();
        let start = s.settings().frame;
        let mut st = ControlState::new(&start);
        apply(Action::MoreVpls, &mut s, &mut st);
        assert_eq!(s.settings().frame.vpls, 512);
        for _ in 0..20 {
            apply(Action::FewerVpls, &mut s, &mut st);
        }
        assert_eq!(s.settings().frame.vpls, 1);
        apply(Action::NextInterleave, &mut s, &mut st);
        assert_eq!(s.settings().frame.interleave, (16, 16));
        apply(Action::NextInterleave, &mut s, &mut st);
        assert_eq!(s.settings().frame.interleave, (1, 1));
        apply(Action::ToggleClamp, &mut s, &mut st);
        assert_eq!(s.settings().frame.clamp, 0.0);
        apply(Action::ToggleClamp, &mut s, &mut st);
        assert_eq!(s.settings().frame.clamp, start.clamp);
        apply(Action::ClampUp, &mut s, &mut st);
        assert_eq!(s.settings().frame.clamp, 10.0 * start.clamp);
        apply(Action::ToggleFilter, &mut s, &mut st);
        assert_eq!(s.settings().frame.filter, None);
        apply(Action::ToggleFilter, &mut s, &mut st);
        assert_eq!(s.settings().frame.filter, start.filter);
        apply(Action::ToggleChains, &mut s, &mut st);
        assert!(s.settings().fresh_chains);
        assert_eq!(action_for(KeyCode::KeyB), Some(Action::ToggleCompensation));
        apply(Action::ToggleCompensation, &mut s, &mut st);
        assert_eq!(s.settings().frame.compensate, !start.compensate);
        apply(Action::ToggleCompensation, &mut s, &mut st);
        assert_eq!(s.settings().frame.compensate, start.compensate);
        assert_eq!(apply(Action::Screenshot, &mut s, &mut st), None);
    }
}
