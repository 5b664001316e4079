//! The GPU engine: `shaders/turning.wgsl` through wgpu. Geometry is prepared by
//! [`TurningScene`] in f64 and uploaded as hi + lo f32 pairs; the kernel works in
//! sample-relative coordinates so f32 resolves sub-nanometre depths. Grids whose
//! result does not fit one storage binding are processed in tiles.

use super::scene::{Branch, TurningScene};
use super::{EngineError, EngineInfo, Progress, RemovalEngine};
use crate::field::DexelField;
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

/// The kernel source, as compiled (tests validate it with naga).
pub const TURNING_SHADER: &str = include_str!("../../shaders/turning.wgsl");

/// Threads per workgroup (`@workgroup_size` in the shader).
const WORKGROUP_SIZE: u32 = 64;
/// Samples per dispatch at most, so progress moves and no dispatch runs for minutes.
const MAX_TILE_SAMPLES: u64 = 1 << 22;

/// Rust twins of the shader's structs; `tests/shaders.rs` checks their layouts match.
pub mod layout {
    use super::{Pod, Zeroable};

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct Params {
        pub ring_count: u32,
        pub azimuth_count: u32,
        pub sample_offset: u32,
        pub sample_count: u32,
        pub pose_count: u32,
        pub steps_per_rev: u32,
        pub base_steps: i32,
        pub dispatch_width: u32,
        pub nose_radius_mm: f32,
        pub cos_half_span: f32,
        pub stock_top_mm: f32,
        pub _padding: f32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct Ring {
        pub r_hi: f32,
        pub r_lo: f32,
        pub z_hi: f32,
        pub z_lo: f32,
        pub normal_r: f32,
        pub normal_z: f32,
        pub direct_first: u32,
        pub direct_last: u32,
        pub mirrored_first: u32,
        pub mirrored_last: u32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct Phase {
        pub direct_whole: u32,
        pub direct_fraction: f32,
        pub mirrored_whole: u32,
        pub mirrored_fraction: f32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct Pose {
        pub x_hi: f32,
        pub x_lo: f32,
        pub z_hi: f32,
        pub z_lo: f32,
        pub b_rad: f32,
        pub _padding: f32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct Dexel {
        pub depth_mm: f32,
        pub pass_id: u32,
    }
}

/// Splits an f64 into f32 hi + lo with hi + lo = value to ~1e-15 relative.
pub fn split_f64(value: f64) -> (f32, f32) {
    let hi = value as f32;
    (hi, (value - hi as f64) as f32)
}

pub struct GpuEngine {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    bind_group_layout: wgpu::BindGroupLayout,
    info: EngineInfo,
    max_binding_bytes: u64,
    /// Caps the samples per tile below what the adapter allows (tests use it to force tiling).
    pub max_tile_samples: u64,
}

impl GpuEngine {
    /// Opens the best adapter wgpu finds (honouring `WGPU_BACKEND` / `WGPU_ADAPTER_NAME`).
    /// Fails with a clear message when there is none.
    pub fn new() -> Result<Self, EngineError> {
        // Compute needs no window system: skip the GL backend (whose EGL probing only
        // prints noise) unless WGPU_BACKEND asks for it.
        let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        descriptor.backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
        let instance = wgpu::Instance::new(descriptor);
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|err| {
            EngineError(format!(
                "no GPU adapter found ({err}); install a Vulkan driver (on Debian: apt-get install mesa-vulkan-drivers for the lavapipe software adapter) or use --engine cpu"
            ))
        })?;
        let adapter_info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("toolmark"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|err| {
            EngineError(format!(
                "GPU adapter {} refused a device: {err}",
                adapter_info.name
            ))
        })?;

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("turning.wgsl"),
            source: wgpu::ShaderSource::Wgsl(TURNING_SHADER.into()),
        });
        let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("turning bindings"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1, true),
                storage(2, true),
                storage(3, true),
                storage(4, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("turning layout"),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("remove_turning"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("remove_turning"),
            compilation_options: Default::default(),
            cache: None,
        });

        let info = EngineInfo {
            kind: "gpu".into(),
            adapter: adapter_info.name.clone(),
            backend: format!("{:?}", adapter_info.backend),
            driver: format!("{} {}", adapter_info.driver, adapter_info.driver_info)
                .trim()
                .to_string(),
            device_type: format!("{:?}", adapter_info.device_type),
        };
        Ok(Self {
            device,
            queue,
            pipeline,
            bind_group_layout,
            info,
            max_binding_bytes: limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size),
            max_tile_samples: MAX_TILE_SAMPLES,
        })
    }

    fn upload<T: Pod>(&self, label: &str, items: &[T]) -> Result<wgpu::Buffer, EngineError> {
        let bytes: &[u8] = bytemuck::cast_slice(items);
        if bytes.len() as u64 > self.max_binding_bytes {
            return Err(EngineError(format!(
                "{label} needs {} MiB, more than the adapter's {} MiB storage binding; reduce the grid or the path length",
                bytes.len() >> 20,
                self.max_binding_bytes >> 20
            )));
        }
        // wgpu rejects zero-sized bindings; pad empty arrays to one element.
        let padded;
        let contents = if bytes.is_empty() {
            padded = vec![0u8; std::mem::size_of::<T>().max(4)];
            &padded[..]
        } else {
            bytes
        };
        Ok(self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            }))
    }

    fn read_back(&self, buffer: &wgpu::Buffer) -> Result<Vec<layout::Dexel>, EngineError> {
        let slice = buffer.slice(..);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |result| {
            let _ = sender.send(result);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|err| EngineError(format!("GPU wait failed: {err}")))?;
        receiver
            .recv()
            .map_err(|_| EngineError("GPU read-back was dropped".into()))?
            .map_err(|err| EngineError(format!("GPU read-back failed: {err}")))?;
        let view = slice
            .get_mapped_range()
            .map_err(|err| EngineError(format!("GPU read-back mapping failed: {err:?}")))?;
        let dexels = bytemuck::cast_slice::<u8, layout::Dexel>(&view).to_vec();
        drop(view);
        buffer.unmap();
        Ok(dexels)
    }
}

/// The scene's rings, phases and poses in the shader's layouts.
fn gpu_inputs(scene: &TurningScene) -> (Vec<layout::Ring>, Vec<layout::Phase>, Vec<layout::Pose>) {
    let rings = scene
        .grid
        .rings
        .iter()
        .zip(&scene.ring_revs)
        .map(|(ring, revs)| {
            let (r_hi, r_lo) = split_f64(ring.radius_mm);
            let (z_hi, z_lo) = split_f64(ring.height_mm);
            let [direct, mirrored] = *revs;
            layout::Ring {
                r_hi,
                r_lo,
                z_hi,
                z_lo,
                normal_r: ring.normal.x as f32,
                normal_z: ring.normal.y as f32,
                direct_first: direct.first,
                direct_last: direct.last,
                mirrored_first: mirrored.first,
                mirrored_last: mirrored.last,
            }
        })
        .collect();
    let phases = scene
        .azimuth_phases
        .iter()
        .map(|phases| {
            let direct = phases[Branch::Direct as usize];
            let mirrored = phases[Branch::Mirrored as usize];
            layout::Phase {
                direct_whole: direct.whole_steps,
                direct_fraction: direct.fraction as f32,
                mirrored_whole: mirrored.whole_steps,
                mirrored_fraction: mirrored.fraction as f32,
            }
        })
        .collect();
    let poses = scene
        .poses
        .poses
        .iter()
        .map(|pose| {
            let (x_hi, x_lo) = split_f64(pose.x_mm);
            let (z_hi, z_lo) = split_f64(pose.z_mm);
            layout::Pose {
                x_hi,
                x_lo,
                z_hi,
                z_lo,
                b_rad: pose.b_rad as f32,
                _padding: 0.0,
            }
        })
        .collect();
    (rings, phases, poses)
}

impl RemovalEngine for GpuEngine {
    fn info(&self) -> EngineInfo {
        self.info.clone()
    }

    fn remove(
        &mut self,
        scene: &TurningScene,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        let sample_count = scene.grid.sample_count() as u64;
        if sample_count > u32::MAX as u64 {
            return Err(EngineError(format!(
                "{sample_count} samples exceed the GPU engine's 2³² sample index"
            )));
        }
        let (rings, phases, poses) = gpu_inputs(scene);
        let ring_buffer = self.upload("rings", &rings)?;
        let phase_buffer = self.upload("phases", &phases)?;
        let pose_buffer = self.upload("poses", &poses)?;

        let dexel_bytes = std::mem::size_of::<layout::Dexel>() as u64;
        let tile_samples = (self.max_binding_bytes / dexel_bytes)
            .min(self.max_tile_samples)
            .min(sample_count)
            .max(1);
        let tile_bytes = tile_samples * dexel_bytes;
        let output = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dexels"),
            size: tile_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dexels read-back"),
            size: tile_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let params_buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: std::mem::size_of::<layout::Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("turning bindings"),
            layout: &self.bind_group_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: ring_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: phase_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: pose_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: output.as_entire_binding(),
                },
            ],
        });

        let mut depth_mm = Vec::with_capacity(sample_count as usize);
        let mut pass = Vec::with_capacity(sample_count as usize);
        let mut offset = 0u64;
        while offset < sample_count {
            let count = tile_samples.min(sample_count - offset);
            let groups = count.div_ceil(WORKGROUP_SIZE as u64) as u32;
            let groups_x = groups.min(65_535);
            let groups_y = groups.div_ceil(groups_x);
            let params = layout::Params {
                ring_count: scene.grid.ring_count() as u32,
                azimuth_count: scene.grid.azimuths,
                sample_offset: offset as u32,
                sample_count: count as u32,
                pose_count: scene.poses.poses.len() as u32,
                steps_per_rev: scene.poses.steps_per_rev,
                base_steps: i32::try_from(scene.base_steps).map_err(|_| {
                    EngineError("pose table start is too far from spindle angle 0".into())
                })?,
                dispatch_width: groups_x * WORKGROUP_SIZE,
                nose_radius_mm: scene.tool.nose_radius_mm as f32,
                cos_half_span: scene.cos_half_span() as f32,
                stock_top_mm: scene.stock_top_mm as f32,
                _padding: 0.0,
            };
            self.queue
                .write_buffer(&params_buffer, 0, bytemuck::bytes_of(&params));
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("turning"),
                });
            {
                let mut compute = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("remove_turning"),
                    timestamp_writes: None,
                });
                compute.set_pipeline(&self.pipeline);
                compute.set_bind_group(0, &bind_group, &[]);
                compute.dispatch_workgroups(groups_x, groups_y, 1);
            }
            let bytes = count * dexel_bytes;
            encoder.copy_buffer_to_buffer(&output, 0, &staging, 0, bytes);
            self.queue.submit([encoder.finish()]);
            let dexels = self.read_back(&staging)?;
            for dexel in &dexels[..count as usize] {
                depth_mm.push(dexel.depth_mm as f64);
                pass.push(dexel.pass_id);
            }
            offset += count;
            progress(offset, sample_count);
        }
        Ok(DexelField { depth_mm, pass })
    }
}
