//! Window events → [`InputState`]: which keys are held, and the mouse motion and scrolling
//! gathered since the last frame.

use std::collections::HashSet;

use glam::Vec2;
use winit::event::{ElementState, MouseScrollDelta};
use winit::keyboard::KeyCode;

use citywalk_runtime::controller::InputState;

/// Pixels of touchpad scrolling that count as one wheel step.
const PIXELS_PER_SCROLL_STEP: f32 = 40.0;

/// One-shot commands bound to keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// F or Tab: walk ↔ fly.
    ToggleMode,
    /// M: mouse look on / off (without holding the right button).
    ToggleMouseLook,
    /// O or Home: back to the overview camera (fly mode).
    Overview,
    /// Escape: leave mouse look, or quit when it is off.
    Escape,
    /// R: start recording the camera path, or stop and write it.
    ToggleRecording,
    /// H: show or hide the overlay panel.
    ToggleOverlay,
    /// B: frustum / B-Quadtree culling on / off.
    ToggleFrustum,
    /// C: HZB occlusion culling on / off (every stage off draws every building, brute force).
    ToggleCulling,
    /// V: the virtual-occluder pre-pass on / off (scene packages with occluders).
    ToggleOccluders,
    /// N: the occluder gate of the early set on / off (with the pre-pass).
    ToggleOccluderGate,
    /// P: the `auto` plan on / off (stages chosen by their measured cost).
    ToggleAuto,
    /// L: the LOD cut on / off (scene packages with a cluster tree).
    ToggleLod,
    /// K: LOD criterion Chang ↔ Yang.
    ToggleCriterion,
    /// T: cluster meshes textured / flat (packages with cluster textures).
    ToggleClusterTextures,
    /// G: the next debug view (off → pyramid → clusters → occluders → off).
    NextDebugView,
    /// `]`: a coarser pyramid level in the pyramid view.
    CoarserMip,
    /// `[`: a finer pyramid level.
    FinerMip,
}

impl Command {
    fn for_key(key: KeyCode) -> Option<Command> {
        match key {
            KeyCode::KeyF | KeyCode::Tab => Some(Command::ToggleMode),
            KeyCode::KeyM => Some(Command::ToggleMouseLook),
            KeyCode::KeyO | KeyCode::Home => Some(Command::Overview),
            KeyCode::Escape => Some(Command::Escape),
            KeyCode::KeyR => Some(Command::ToggleRecording),
            KeyCode::KeyH => Some(Command::ToggleOverlay),
            KeyCode::KeyC => Some(Command::ToggleCulling),
            KeyCode::KeyV => Some(Command::ToggleOccluders),
            KeyCode::KeyN => Some(Command::ToggleOccluderGate),
            KeyCode::KeyP => Some(Command::ToggleAuto),
            KeyCode::KeyB => Some(Command::ToggleFrustum),
            KeyCode::KeyL => Some(Command::ToggleLod),
            KeyCode::KeyK => Some(Command::ToggleCriterion),
            KeyCode::KeyT => Some(Command::ToggleClusterTextures),
            KeyCode::KeyG => Some(Command::NextDebugView),
            KeyCode::BracketRight => Some(Command::CoarserMip),
            KeyCode::BracketLeft => Some(Command::FinerMip),
            _ => None,
        }
    }
}

/// The keys and mouse as seen by the viewer.
#[derive(Debug, Default)]
pub struct InputTracker {
    held: HashSet<KeyCode>,
    look_delta_px: Vec2,
    scroll_steps: f32,
}

impl InputTracker {
    /// Records a key press or release; returns the command a fresh press triggers.
    pub fn key(&mut self, key: KeyCode, state: ElementState, repeat: bool) -> Option<Command> {
        match state {
            ElementState::Pressed => {
                self.held.insert(key);
                if repeat { None } else { Command::for_key(key) }
            }
            ElementState::Released => {
                self.held.remove(&key);
                None
            }
        }
    }

    /// Adds raw mouse motion (pixels, +y down); counted only while mouse look is on.
    pub fn mouse_motion(&mut self, dx: f64, dy: f64) {
        self.look_delta_px += Vec2::new(dx as f32, dy as f32);
    }

    /// Adds scrolling.
    pub fn scroll(&mut self, delta: MouseScrollDelta) {
        self.scroll_steps += match delta {
            MouseScrollDelta::LineDelta(_, y) => y,
            MouseScrollDelta::PixelDelta(p) => p.y as f32 / PIXELS_PER_SCROLL_STEP,
        };
    }

    /// Forgets held keys (on focus loss, so no key stays stuck).
    pub fn release_all(&mut self) {
        self.held.clear();
    }

    /// The input for this frame; mouse motion and scrolling are consumed.
    pub fn take(&mut self) -> InputState {
        let axis = |plus: &[KeyCode], minus: &[KeyCode]| {
            let pressed = |keys: &[KeyCode]| keys.iter().any(|k| self.held.contains(k));
            f32::from(u8::from(pressed(plus))) - f32::from(u8::from(pressed(minus)))
        };
        let input = InputState {
            forward: axis(
                &[KeyCode::KeyW, KeyCode::ArrowUp],
                &[KeyCode::KeyS, KeyCode::ArrowDown],
            ),
            right: axis(
                &[KeyCode::KeyD, KeyCode::ArrowRight],
                &[KeyCode::KeyA, KeyCode::ArrowLeft],
            ),
            up: axis(
                &[KeyCode::KeyE, KeyCode::Space, KeyCode::PageUp],
                &[
                    KeyCode::KeyQ,
                    KeyCode::ControlLeft,
                    KeyCode::ControlRight,
                    KeyCode::PageDown,
                ],
            ),
            run: self.held.contains(&KeyCode::ShiftLeft)
                || self.held.contains(&KeyCode::ShiftRight),
            look_delta_px: self.look_delta_px,
            scroll_steps: self.scroll_steps,
        };
        self.look_delta_px = Vec2::ZERO;
        self.scroll_steps = 0.0;
        input
    }
}

/// The key help shown in the log when the viewer starts.
pub const KEY_HELP: &str = "WASD / arrows move, Shift runs, mouse looks while the right button \
is held (M toggles mouse look, Esc releases it or quits), F / Tab switch walk <-> fly, \
fly: E / Space up, Q / Ctrl down, wheel changes speed, O goes to the overview, R starts / stops \
recording the camera path, H shows / hides the overlay, B / C / V / L switch frustum (B-Quadtree) \
culling, HZB occlusion culling, the virtual-occluder pre-pass and the LOD cut on / off (all off: \
brute force), N the occluder gate of last frame's visible set, K switches the LOD criterion \
Chang <-> Yang, G cycles the debug views (pyramid, clusters, occluders), [ and ] pick the \
pyramid level";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_map_to_axes_and_commands() {
        let mut t = InputTracker::default();
        assert_eq!(t.key(KeyCode::KeyW, ElementState::Pressed, false), None);
        t.key(KeyCode::KeyA, ElementState::Pressed, false);
        t.key(KeyCode::ShiftLeft, ElementState::Pressed, false);
        t.mouse_motion(3.0, -2.0);
        t.scroll(MouseScrollDelta::LineDelta(0.0, 2.0));
        let i = t.take();
        assert_eq!((i.forward, i.right, i.up, i.run), (1.0, -1.0, 0.0, true));
        assert_eq!(i.look_delta_px, Vec2::new(3.0, -2.0));
        assert_eq!(i.scroll_steps, 2.0);
        // Motion and scrolling are consumed, held keys are not.
        let i = t.take();
        assert_eq!(
            (i.forward, i.look_delta_px, i.scroll_steps),
            (1.0, Vec2::ZERO, 0.0)
        );
        t.key(KeyCode::KeyW, ElementState::Released, false);
        t.key(KeyCode::KeyS, ElementState::Pressed, false);
        assert_eq!(t.take().forward, -1.0);
        assert_eq!(
            t.key(KeyCode::KeyF, ElementState::Pressed, false),
            Some(Command::ToggleMode)
        );
        assert_eq!(
            t.key(KeyCode::KeyF, ElementState::Pressed, true),
            None,
            "auto-repeat"
        );
        assert_eq!(
            t.key(KeyCode::Tab, ElementState::Pressed, false),
            Some(Command::ToggleMode)
        );
        assert_eq!(
            t.key(KeyCode::KeyR, ElementState::Pressed, false),
            Some(Command::ToggleRecording)
        );
        assert_eq!(
            t.key(KeyCode::KeyH, ElementState::Pressed, false),
            Some(Command::ToggleOverlay)
        );
        assert_eq!(
            t.key(KeyCode::KeyC, ElementState::Pressed, false),
            Some(Command::ToggleCulling)
        );
        assert_eq!(
            t.key(KeyCode::KeyV, ElementState::Pressed, false),
            Some(Command::ToggleOccluders)
        );
        assert_eq!(
            t.key(KeyCode::KeyN, ElementState::Pressed, false),
            Some(Command::ToggleOccluderGate)
        );
        for (key, command) in [
            (KeyCode::KeyP, Command::ToggleAuto),
            (KeyCode::KeyB, Command::ToggleFrustum),
            (KeyCode::KeyL, Command::ToggleLod),
            (KeyCode::KeyT, Command::ToggleClusterTextures),
            (KeyCode::KeyK, Command::ToggleCriterion),
            (KeyCode::KeyG, Command::NextDebugView),
            (KeyCode::BracketRight, Command::CoarserMip),
            (KeyCode::BracketLeft, Command::FinerMip),
        ] {
            assert_eq!(t.key(key, ElementState::Pressed, false), Some(command));
        }
        t.release_all();
        assert_eq!(t.take(), InputState::default());
    }
}
