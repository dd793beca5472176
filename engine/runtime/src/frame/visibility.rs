//! Which draw ids the last frame's cull kept: the early pass's set, kept on the GPU.
//!
//! niagara's `drawVisibility`: the GPU marks, and the next frame's early entry point reads, a
//! stamp per draw id (`shaders/wgsl/hzb_cull.wgsl`); the CPU never walks or uploads the set.
//! Stamps rather than flags, so that a draw id that left the candidates (the LOD cut moved, the
//! frustum turned) expires by itself instead of needing a clear: a draw id counts as visible
//! last frame only when its stamp is exactly last frame's.

use crate::gpu::GpuContext;

/// The stamp of the first frame: last frame's (1) is newer than the zeroed buffer's 0.
const FIRST_STAMP: u32 = 2;

/// Per-draw-id visibility on the GPU, carried from frame to frame (one per camera path or view),
/// with a CPU copy of the buildings it holds as of the last frame whose report was read. Not
/// `Clone`: two frames streams must not share stamps; [`Visibility::fork`] copies them.
#[derive(Debug, Default)]
pub struct Visibility {
    /// The stamps (`u32` per draw id), made for the first frame of a scene's shape.
    stamps: Option<Stamps>,
    /// The stamp of the frame rendered last (0 before any).
    stamp: u32,
    /// The buildings visible in the frame whose report was read last, ascending
    /// ([`Visibility::is_visible`]).
    mirror: Vec<u32>,
    /// The tree cull's kept lists ([`crate::hzb::tree_cull`]), made for the first tree frame.
    tree: Option<TreeLists>,
}

/// Two halves of kept draw ids: the last tree frame's and the one being written.
#[derive(Debug)]
struct TreeLists {
    buffer: wgpu::Buffer,
    capacity: u32,
    /// The half holding the last tree frame's ids.
    last_half: u32,
    /// The stamp of the frame that wrote `last_half` (0: none).
    written: u32,
}

#[derive(Debug)]
struct Stamps {
    buffer: wgpu::Buffer,
    draw_ids: u32,
}

impl Visibility {
    /// Nothing visible (the state at the start of a camera path): the next frame's stamp skips
    /// one, so no stamp on the GPU equals "last frame".
    pub fn reset(&mut self) {
        if self.stamp != 0 {
            self.stamp += 1;
        }
        self.mirror.clear();
    }

    /// Whether building `id` was visible in the last frame whose report was read (a frame
    /// rendered with [`crate::frame::CullingRenderer::render`] or `render_lod` has been).
    pub fn is_visible(&self, id: u32) -> bool {
        self.mirror.binary_search(&id).is_ok()
    }

    /// The buildings of [`Visibility::is_visible`], in id order.
    pub fn visible_ids(&self) -> Vec<u32> {
        self.mirror.clone()
    }

    /// An independent copy (the GPU stamps copied, on the queue, after what was submitted).
    pub fn fork(&self, gpu: &GpuContext) -> Visibility {
        let stamps = self.stamps.as_ref().map(|s| {
            let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("visibility stamps"),
                size: s.buffer.size(),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("visibility fork"),
                });
            encoder.copy_buffer_to_buffer(&s.buffer, 0, &buffer, 0, s.buffer.size());
            gpu.queue.submit([encoder.finish()]);
            Stamps {
                buffer,
                draw_ids: s.draw_ids,
            }
        });
        // The tree lists are not copied: the fork's first tree frame draws nothing early
        // (a hint, not a promise).
        Visibility {
            stamps,
            stamp: self.stamp,
            mirror: self.mirror.clone(),
            tree: None,
        }
    }

    /// Readies the stamps for a frame over a scene of `draw_ids` draw ids and returns the
    /// buffer and this frame's stamp. A buffer of another size belongs to another scene and is
    /// replaced by a zeroed one (nothing visible).
    pub(super) fn begin_frame(&mut self, gpu: &GpuContext, draw_ids: u32) -> (&wgpu::Buffer, u32) {
        let fits = self.stamps.as_ref().is_some_and(|s| s.draw_ids == draw_ids);
        if !fits {
            self.stamps = Some(Stamps {
                buffer: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("visibility stamps"),
                    size: u64::from(draw_ids.max(1)) * 4,
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                }),
                draw_ids,
            });
            self.stamp = FIRST_STAMP - 1;
            self.mirror.clear();
        }
        self.stamp = self.stamp.max(FIRST_STAMP - 1) + 1;
        let stamps = self.stamps.as_ref().expect("made above");
        (&stamps.buffer, self.stamp)
    }

    /// Sets the CPU copy to the buildings `ids`, ascending.
    pub(super) fn mirror_ids(&mut self, ids: Vec<u32>) {
        self.mirror = ids;
    }

    /// The tree cull's kept lists for the frame of stamp `frame_stamp` (after
    /// [`Visibility::begin_frame`]), `capacity` entries per half: the buffer, the half holding
    /// last frame's ids, and whether it does (the last frame was a tree frame of this stream).
    pub(super) fn tree_lists(
        &mut self,
        gpu: &GpuContext,
        capacity: u32,
        frame_stamp: u32,
    ) -> (wgpu::Buffer, u32, bool) {
        if self.tree.as_ref().is_none_or(|t| t.capacity != capacity) {
            self.tree = Some(TreeLists {
                buffer: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("tree cull kept lists"),
                    size: crate::hzb::tree_cull::lists_bytes(capacity),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                }),
                capacity,
                last_half: 0,
                written: 0,
            });
        }
        let t = self.tree.as_ref().expect("made above");
        let valid = t.written != 0 && t.written + 1 == frame_stamp;
        (t.buffer.clone(), t.last_half, valid)
    }

    /// The tree frame of stamp `frame_stamp` wrote the other half: it is last frame's for the
    /// next one.
    pub(super) fn tree_written(&mut self, frame_stamp: u32) {
        if let Some(t) = &mut self.tree {
            t.last_half = 1 - t.last_half;
            t.written = frame_stamp;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mirror_follows_the_ids_and_a_reset_clears_it() {
        let mut v = Visibility::default();
        assert!(!v.is_visible(0));
        v.mirror_ids(vec![0, 2]);
        assert_eq!(v.visible_ids(), vec![0, 2]);
        assert!(v.is_visible(2) && !v.is_visible(1) && !v.is_visible(7));
        v.mirror_ids(vec![1]);
        assert_eq!(v.visible_ids(), vec![1]);
        v.reset();
        assert!(!v.is_visible(1));
    }

    #[test]
    fn stamps_advance_per_frame_and_a_reset_skips_one() {
        let Ok(gpu) = GpuContext::headless() else {
            assert!(std::env::var_os("CI").is_none(), "no adapter in CI");
            return;
        };
        let mut v = Visibility::default();
        let (_, first) = v.begin_frame(&gpu, 10);
        assert_eq!(first, FIRST_STAMP);
        let (_, second) = v.begin_frame(&gpu, 10);
        assert_eq!(second, first + 1, "consecutive frames");
        v.reset();
        let (_, after_reset) = v.begin_frame(&gpu, 10);
        assert_eq!(after_reset, second + 2, "last frame's stamp is no frame's");
        // Another scene shape: a new zeroed buffer, stamps from the start.
        let (_, other) = v.begin_frame(&gpu, 11);
        assert_eq!(other, FIRST_STAMP);
    }
}
