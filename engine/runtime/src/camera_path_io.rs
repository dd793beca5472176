//! Camera paths ([`citywalk_scenes::camera_path`]) meet the engine's [`Camera`]: conversion
//! both ways, a recorder that collects one pose per frame and writes a `.path` file, and a
//! player that hands out one camera per frame. Both are plain data, testable without a window.

use std::path::{Path, PathBuf};

use citywalk_scenes::camera_path::{CameraPath, CameraPose};

use crate::camera::Camera;

/// The camera a pose describes, with the path's vertical field of view (degrees).
pub fn camera_from_pose(pose: &CameraPose, fov_y_deg: f32) -> Camera {
    Camera {
        fov_y_rad: fov_y_deg.to_radians(),
        ..Camera::new(
            pose.position,
            pose.yaw_deg.to_radians(),
            pose.pitch_deg.to_radians(),
        )
    }
}

/// The pose of a camera (position, yaw and pitch in degrees).
pub fn pose_from_camera(camera: &Camera) -> CameraPose {
    CameraPose {
        position: camera.position,
        yaw_deg: camera.yaw_rad.to_degrees(),
        pitch_deg: camera.pitch_rad.to_degrees(),
    }
}

/// Why a recorded path could not be saved.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("nothing recorded: no frame was drawn while recording to {0}")]
    Empty(PathBuf),
    #[error("writing the recorded path {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Collects the camera of every frame drawn while recording; [`PathRecorder::save`] writes them
/// with [`CameraPath::write`].
#[derive(Debug, Clone)]
pub struct PathRecorder {
    output: PathBuf,
    path: CameraPath,
}

impl PathRecorder {
    /// A recorder that will write to `output`; `name` goes into the file's `name` line.
    pub fn new(output: &Path, name: &str) -> PathRecorder {
        PathRecorder {
            output: output.to_path_buf(),
            path: CameraPath {
                name: name.to_string(),
                fov_y_deg: Camera::DEFAULT_FOV_Y_RAD.to_degrees(),
                poses: Vec::new(),
            },
        }
    }

    /// Adds the camera of one frame. The path's field of view is the first camera's (a path
    /// has one field of view).
    pub fn push(&mut self, camera: &Camera) {
        if self.path.poses.is_empty() {
            // Rounded to 1e-4° so that 60° does not come back as 60.000004° from radians.
            self.path.fov_y_deg = (camera.fov_y_rad.to_degrees() * 1e4).round() / 1e4;
        }
        self.path.poses.push(pose_from_camera(camera));
    }

    /// Poses recorded so far.
    pub fn len(&self) -> usize {
        self.path.poses.len()
    }

    /// Whether no pose was recorded yet.
    pub fn is_empty(&self) -> bool {
        self.path.poses.is_empty()
    }

    /// Where [`PathRecorder::save`] writes.
    pub fn output(&self) -> &Path {
        &self.output
    }

    /// The path recorded so far.
    pub fn path(&self) -> &CameraPath {
        &self.path
    }

    /// Writes the recorded poses to the output file; a recording without poses is an error
    /// (the format needs at least one pose).
    pub fn save(&self) -> Result<&Path, RecordError> {
        if self.path.poses.is_empty() {
            return Err(RecordError::Empty(self.output.clone()));
        }
        self.path
            .write(&self.output)
            .map_err(|source| RecordError::Write {
                path: self.output.clone(),
                source,
            })?;
        Ok(&self.output)
    }
}

/// What happens after the last pose of a played path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlayEnd {
    /// Start again at the first pose.
    Loop,
    /// Stop: [`PathPlayer::next_camera`] returns `None` from then on.
    Stop,
}

/// Hands out the poses of a path as cameras, one per call (one per frame).
#[derive(Debug, Clone)]
pub struct PathPlayer {
    path: CameraPath,
    next: usize,
    end: PlayEnd,
}

impl PathPlayer {
    pub fn new(path: CameraPath, end: PlayEnd) -> PathPlayer {
        PathPlayer { path, next: 0, end }
    }

    /// The camera of the next frame, or `None` once a [`PlayEnd::Stop`] path is over (or the
    /// path has no pose).
    pub fn next_camera(&mut self) -> Option<Camera> {
        if self.next >= self.path.poses.len() {
            if self.end == PlayEnd::Stop || self.path.poses.is_empty() {
                return None;
            }
            self.next = 0;
        }
        let pose = &self.path.poses[self.next];
        self.next += 1;
        Some(camera_from_pose(pose, self.path.fov_y_deg))
    }

    /// Index of the pose the last [`PathPlayer::next_camera`] returned, and the pose count.
    pub fn progress(&self) -> (usize, usize) {
        (self.next.saturating_sub(1), self.path.poses.len())
    }

    /// Whether a [`PlayEnd::Stop`] path has handed out its last pose.
    pub fn finished(&self) -> bool {
        self.end == PlayEnd::Stop && self.next >= self.path.poses.len()
    }

    /// The path played.
    pub fn path(&self) -> &CameraPath {
        &self.path
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    fn camera(i: usize) -> Camera {
        let f = i as f32;
        Camera::new(
            Vec3::new(f, -2.0 * f, 1.7 + f),
            (10.0 * f).to_radians(),
            (-3.0 * f).to_radians(),
        )
    }

    #[test]
    fn poses_and_cameras_convert_both_ways() {
        let c = camera(3);
        let back = camera_from_pose(&pose_from_camera(&c), 60.0);
        assert!((back.position - c.position).length() < 1e-6);
        assert!((back.yaw_rad - c.yaw_rad).abs() < 1e-6);
        assert!((back.pitch_rad - c.pitch_rad).abs() < 1e-6);
        assert!((back.fov_y_rad - 60f32.to_radians()).abs() < 1e-6);
    }

    #[test]
    fn a_recording_written_and_read_back_plays_the_same_cameras() {
        let dir = std::env::temp_dir().join(format!("citywalk-record-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let file = dir.join("walk.path");
        let mut recorder = PathRecorder::new(&file, "recorded");
        assert!(matches!(recorder.save(), Err(RecordError::Empty(_))));
        for i in 0..7 {
            recorder.push(&camera(i));
        }
        assert_eq!(recorder.len(), 7);
        assert_eq!(recorder.save().expect("saved"), file.as_path());
        let read = CameraPath::read(&file).expect("the recording parses");
        assert_eq!(read.name, "recorded");
        assert_eq!(read.fov_y_deg, 60.0);
        assert_eq!(read.poses.len(), 7);

        let mut player = PathPlayer::new(read, PlayEnd::Stop);
        for i in 0..7 {
            let played = player.next_camera().expect("a pose per frame");
            let want = camera(i);
            assert!(
                (played.position - want.position).length() < 1e-4,
                "pose {i}"
            );
            assert!((played.yaw_rad - want.yaw_rad).abs() < 1e-4, "pose {i}");
            assert!((played.pitch_rad - want.pitch_rad).abs() < 1e-4, "pose {i}");
            assert_eq!(player.progress(), (i, 7));
        }
        assert!(player.finished());
        assert_eq!(player.next_camera(), None);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_looping_player_starts_again() {
        let mut recorder = PathRecorder::new(Path::new("unused.path"), "loop");
        for i in 0..3 {
            recorder.push(&camera(i));
        }
        let mut player = PathPlayer::new(recorder.path().clone(), PlayEnd::Loop);
        let xs: Vec<f32> = (0..7)
            .map(|_| player.next_camera().expect("loops").position.x)
            .collect();
        assert_eq!(xs, [0.0, 1.0, 2.0, 0.0, 1.0, 2.0, 0.0]);
        assert!(!player.finished());
    }
}
