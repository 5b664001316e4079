//! The GPU engine: `shaders/turning.wgsl` and `shaders/generating.wgsl` through wgpu.
//! Geometry is prepared by the scenes in f64 and uploaded as hi + lo f32 pairs or as
//! small local-frame differences; the kernels work in sample-relative coordinates so
//! f32 resolves sub-nanometre depths. Grids whose result does not fit one storage
//! binding are processed in tiles.

use super::cpu::RAY_REFINEMENTS;
use super::cpu_generating::MAX_NEWTON_STEPS;
use super::generating_scene::{GeneratingScene, MAX_CONTACTS};
use super::scene::TurningScene;
use super::{EngineError, EngineInfo, Progress, RemovalEngine, Scene};
use crate::field::DexelField;
use crate::geometry::tool::EDGE_REFINEMENTS;
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

/// The kernel sources, as compiled (tests validate them with naga).
pub const TURNING_SHADER: &str = include_str!("../../shaders/turning.wgsl");
pub const GENERATING_SHADER: &str = include_str!("../../shaders/generating.wgsl");

/// Newton steps the f32 generating kernel takes per tooth pass (from a start within a
/// tooth spacing, quadratic convergence reaches f32 precision in about four).
const GPU_NEWTON_STEPS: u32 = 8;
const _: () = assert!(GPU_NEWTON_STEPS as usize <= MAX_NEWTON_STEPS);

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
        pub radius_error_mm: f32,
        pub tip_offset_mm: f32,
        pub cos_half_span: f32,
        pub stock_top_mm: f32,
        pub edge_plane_y_mm: f32,
        pub tan_clearance: f32,
        pub start_phase_rad: f32,
        pub azimuth_step_rad: f32,
        pub inverse_step_rad: f32,
        pub deviation_start_rad: f32,
        pub deviation_inverse_step: f32,
        pub deviation_count: u32,
        pub edge_refinements: u32,
        pub ray_refinements: u32,
        pub _padding: u32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct Ring {
        pub r_hi: f32,
        pub r_lo: f32,
        pub z_hi: f32,
        pub z_lo: f32,
        pub q_hi: f32,
        pub q_lo: f32,
        pub normal_r: f32,
        pub normal_z: f32,
        pub direct_azimuth_rad: f32,
        pub _padding: f32,
        pub direct_first: u32,
        pub direct_last: u32,
        pub mirrored_first: u32,
        pub mirrored_last: u32,
        pub flank_first: u32,
        pub flank_last: u32,
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

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct GeneratingParams {
        pub ring_count: u32,
        pub azimuth_count: u32,
        pub sample_offset: u32,
        pub sample_count: u32,
        pub dispatch_width: u32,
        pub teeth: u32,
        pub revolutions: u32,
        pub newton_steps: u32,
        pub cutting_radius_mm: f32,
        pub edge_radius_mm: f32,
        pub stock_top_mm: f32,
        pub speed_ratio: f32,
        pub pitch_rad: f32,
        pub window_rad: f32,
        pub azimuth_step_rad: f32,
        pub passes_per_turn_fraction: f32,
        pub passes_per_turn_whole: i32,
        pub _padding0: u32,
        pub _padding1: u32,
        pub _padding2: u32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct GeneratingRing {
        pub normal_r: f32,
        pub normal_z: f32,
        pub contact_count: u32,
        pub _padding: u32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct GeneratingContact {
        pub depth_mm: f32,
        pub radius_mm: f32,
        pub azimuth_rad: f32,
        pub phase_fraction: f32,
        pub offset_rho: f32,
        pub offset_phi: f32,
        pub offset_z: f32,
        pub phase_whole: i32,
        pub radial_rho: f32,
        pub radial_phi: f32,
        pub radial_z: f32,
        pub _padding0: f32,
        pub tangent_rho: f32,
        pub tangent_phi: f32,
        pub tangent_z: f32,
        pub _padding1: f32,
        pub axis_rho: f32,
        pub axis_phi: f32,
        pub axis_z: f32,
        pub _padding2: f32,
    }

    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub struct AzimuthPhase {
        pub fraction: f32,
        pub whole: i32,
    }
}

/// A count split into its whole part and the fraction in [0, 1), in f64 before the
/// fraction goes to f32 (so a tooth count of 10⁵ keeps its fraction to 1e-7).
pub fn split_count(value: f64) -> (i32, f32) {
    let whole = value.floor();
    (whole as i32, (value - whole) as f32)
}

/// Splits an f64 into f32 hi + lo with hi + lo = value to ~1e-15 relative.
pub fn split_f64(value: f64) -> (f32, f32) {
    let hi = value as f32;
    (hi, (value - hi as f64) as f32)
}

/// A compute pipeline with the bindings both kernels share: 0 the uniform parameters,
/// 1–3 read-only inputs, 4 the dexel output.
struct Kernel {
    pipeline: wgpu::ComputePipeline,
    bind_group_layout: wgpu::BindGroupLayout,
    label: &'static str,
}

pub struct GpuEngine {
    device: wgpu::Device,
    queue: wgpu::Queue,
    turning: Kernel,
    generating: Kernel,
    info: EngineInfo,
    max_binding_bytes: u64,
    /// Caps the samples per tile below what the adapter allows (tests use it to force tiling).
    pub max_tile_samples: u64,
}

impl GpuEngine {
    /// Whether the GPU kernels cover a process (milling runs on the CPU engine only).
    pub fn runs(process: &crate::process::Process) -> bool {
        !matches!(process, crate::process::Process::Milling(_))
    }

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

        let turning = build_kernel(
            &device,
            "remove_turning",
            TURNING_SHADER,
            &adapter_info.name,
        )?;
        let generating = build_kernel(
            &device,
            "remove_generating",
            GENERATING_SHADER,
            &adapter_info.name,
        )?;

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
            turning,
            generating,
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

/// Compiles one kernel; validation errors come back as values, not wgpu's default panic.
fn build_kernel(
    device: &wgpu::Device,
    entry: &'static str,
    source: &str,
    adapter: &str,
) -> Result<Kernel, EngineError> {
    let out_of_memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(entry),
        source: wgpu::ShaderSource::Wgsl(source.into()),
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
        label: Some(entry),
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
        label: Some(entry),
        bind_group_layouts: &[Some(&bind_group_layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    for (scope, what) in [
        (validation, "failed validation"),
        (out_of_memory, "ran out of GPU memory"),
    ] {
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(EngineError(format!(
                "kernel {entry} {what} on {adapter}: {err}"
            )));
        }
    }
    Ok(Kernel {
        pipeline,
        bind_group_layout,
        label: entry,
    })
}

/// The scene's rings and poses in the shader's layouts.
fn gpu_inputs(scene: &TurningScene) -> (Vec<layout::Ring>, Vec<layout::Pose>) {
    let rings = scene
        .grid
        .rings
        .iter()
        .zip(&scene.rings)
        .map(|(ring, passes)| {
            let (r_hi, r_lo) = split_f64(ring.radius_mm);
            let (z_hi, z_lo) = split_f64(ring.height_mm);
            let (q_hi, q_lo) = split_f64(passes.lateral_mm);
            let [direct, mirrored, flank] = passes.revs;
            layout::Ring {
                r_hi,
                r_lo,
                z_hi,
                z_lo,
                q_hi,
                q_lo,
                normal_r: ring.normal.x as f32,
                normal_z: ring.normal.y as f32,
                direct_azimuth_rad: passes.direct_azimuth_rad as f32,
                _padding: 0.0,
                direct_first: direct.first,
                direct_last: direct.last,
                mirrored_first: mirrored.first,
                mirrored_last: mirrored.last,
                flank_first: flank.first,
                flank_last: flank.last,
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
    (rings, poses)
}

/// The uniform parameters of one tile.
fn tile_params(
    scene: &TurningScene,
    offset: u64,
    count: u64,
    dispatch_width: u32,
) -> Result<layout::Params, EngineError> {
    let edge = &scene.edge;
    let deviation = &edge.deviation;
    Ok(layout::Params {
        ring_count: scene.grid.ring_count() as u32,
        azimuth_count: scene.grid.azimuths,
        sample_offset: offset as u32,
        sample_count: count as u32,
        pose_count: scene.poses.poses.len() as u32,
        steps_per_rev: scene.poses.steps_per_rev,
        base_steps: i32::try_from(scene.base_steps)
            .map_err(|_| EngineError("pose table start is too far from spindle angle 0".into()))?,
        dispatch_width,
        nose_radius_mm: edge.nominal_radius_mm as f32,
        radius_error_mm: edge.radius_error_mm as f32,
        tip_offset_mm: edge.tip_offset_mm() as f32,
        cos_half_span: edge.cos_half_span() as f32,
        stock_top_mm: scene.stock_top_mm as f32,
        edge_plane_y_mm: scene.edge_plane_y_mm as f32,
        tan_clearance: scene.tan_clearance as f32,
        start_phase_rad: scene.start_phase_rad as f32,
        azimuth_step_rad: (std::f64::consts::TAU / scene.grid.azimuths as f64) as f32,
        inverse_step_rad: (1.0 / scene.poses.step_rad()) as f32,
        deviation_start_rad: deviation.start_rad as f32,
        deviation_inverse_step: if deviation.step_rad > 0.0 {
            (1.0 / deviation.step_rad) as f32
        } else {
            0.0
        },
        deviation_count: if deviation.is_zero() {
            0
        } else {
            deviation.values_mm.len() as u32
        },
        edge_refinements: EDGE_REFINEMENTS as u32,
        ray_refinements: RAY_REFINEMENTS as u32,
        _padding: 0,
    })
}

impl RemovalEngine for GpuEngine {
    fn info(&self) -> EngineInfo {
        self.info.clone()
    }

    fn remove(&mut self, scene: &Scene, progress: Progress<'_>) -> Result<DexelField, EngineError> {
        match scene {
            Scene::Turning(scene) => self.remove_turning(scene, progress),
            Scene::Generating(scene) => self.remove_generating(scene, progress),
            Scene::Milling(_) => Err(EngineError(
                "the GPU engine does not run milling jobs yet; use --engine cpu (or auto)".into(),
            )),
        }
    }
}

impl GpuEngine {
    fn remove_turning(
        &mut self,
        scene: &TurningScene,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        let (rings, poses) = gpu_inputs(scene);
        let deviation: Vec<f32> = scene
            .edge
            .deviation
            .values_mm
            .iter()
            .map(|&v| v as f32)
            .collect();
        let inputs = [
            self.upload("rings", &rings)?,
            self.upload("poses", &poses)?,
            self.upload("edge deviation", &deviation)?,
        ];
        self.dispatch(
            &self.turning,
            &inputs,
            scene.grid.sample_count() as u64,
            &|offset, count, width| tile_params(scene, offset, count, width),
            progress,
        )
    }

    fn remove_generating(
        &mut self,
        scene: &GeneratingScene,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        let (rings, contacts) = generating_inputs(scene);
        let teeth = scene.teeth;
        let phases: Vec<layout::AzimuthPhase> = match &teeth {
            Some(teeth) => (0..scene.grid.azimuths)
                .map(|j| {
                    let (whole, fraction) = split_count(teeth.passes_in(scene.grid.azimuth_rad(j)));
                    layout::AzimuthPhase { fraction, whole }
                })
                .collect(),
            None => Vec::new(),
        };
        let inputs = [
            self.upload("generating rings", &rings)?,
            self.upload("contacts", &contacts)?,
            self.upload("azimuth phases", &phases)?,
        ];
        let (whole, fraction) = teeth.map_or((0, 0.0), |t| split_count(t.passes_per_turn()));
        let params = |offset: u64, count: u64, width: u32| {
            Ok(layout::GeneratingParams {
                ring_count: scene.grid.ring_count() as u32,
                azimuth_count: scene.grid.azimuths,
                sample_offset: offset as u32,
                sample_count: count as u32,
                dispatch_width: width,
                teeth: teeth.map_or(0, |t| t.count),
                revolutions: teeth.map_or(0, |t| t.revolutions()),
                newton_steps: GPU_NEWTON_STEPS,
                cutting_radius_mm: scene.circle.radius_mm as f32,
                edge_radius_mm: scene.edge_radius_mm as f32,
                stock_top_mm: scene.stock_top_mm as f32,
                speed_ratio: teeth.map_or(1.0, |t| t.speed_ratio) as f32,
                pitch_rad: teeth.map_or(1.0, |t| t.pitch_rad()) as f32,
                window_rad: teeth.map_or(0.0, |t| t.distinct_rad()) as f32,
                azimuth_step_rad: (std::f64::consts::TAU / scene.grid.azimuths as f64) as f32,
                passes_per_turn_fraction: fraction,
                passes_per_turn_whole: whole,
                _padding0: 0,
                _padding1: 0,
                _padding2: 0,
            })
        };
        self.dispatch(
            &self.generating,
            &inputs,
            scene.grid.sample_count() as u64,
            &params,
            progress,
        )
    }

    /// Runs `kernel` over every sample, in tiles that fit one storage binding.
    fn dispatch<P: Pod>(
        &self,
        kernel: &Kernel,
        inputs: &[wgpu::Buffer; 3],
        sample_count: u64,
        params: &dyn Fn(u64, u64, u32) -> Result<P, EngineError>,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        if sample_count > u32::MAX as u64 {
            return Err(EngineError(format!(
                "{sample_count} samples exceed the GPU engine's 2³² sample index"
            )));
        }
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
            size: std::mem::size_of::<P>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let buffers = [&params_buffer, &inputs[0], &inputs[1], &inputs[2], &output];
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding: binding as u32,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(kernel.label),
            layout: &kernel.bind_group_layout,
            entries: &entries,
        });

        let mut depth_mm = Vec::with_capacity(sample_count as usize);
        let mut pass = Vec::with_capacity(sample_count as usize);
        let mut offset = 0u64;
        while offset < sample_count {
            let count = tile_samples.min(sample_count - offset);
            let groups = count.div_ceil(WORKGROUP_SIZE as u64) as u32;
            let groups_x = groups.min(65_535);
            let groups_y = groups.div_ceil(groups_x);
            let tile = params(offset, count, groups_x * WORKGROUP_SIZE)?;
            let out_of_memory = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
            let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
            self.queue
                .write_buffer(&params_buffer, 0, bytemuck::bytes_of(&tile));
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some(kernel.label),
                });
            {
                let mut compute = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(kernel.label),
                    timestamp_writes: None,
                });
                compute.set_pipeline(&kernel.pipeline);
                compute.set_bind_group(0, &bind_group, &[]);
                compute.dispatch_workgroups(groups_x, groups_y, 1);
            }
            encoder.copy_buffer_to_buffer(&output, 0, &staging, 0, count * dexel_bytes);
            self.queue.submit([encoder.finish()]);
            for (scope, what) in [
                (validation, "GPU dispatch failed"),
                (out_of_memory, "out of GPU memory"),
            ] {
                if let Some(err) = pollster::block_on(scope.pop()) {
                    return Err(EngineError(format!("{what}: {err}")));
                }
            }
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

/// A generating scene's rings and contacts (two slots per ring) in the shader's layouts.
fn generating_inputs(
    scene: &GeneratingScene,
) -> (Vec<layout::GeneratingRing>, Vec<layout::GeneratingContact>) {
    let rings = scene
        .grid
        .rings
        .iter()
        .zip(&scene.rings)
        .map(|(ring, contacts)| layout::GeneratingRing {
            normal_r: ring.normal.x as f32,
            normal_z: ring.normal.y as f32,
            contact_count: contacts.len() as u32,
            _padding: 0,
        })
        .collect();
    let mut slots = Vec::with_capacity(scene.rings.len() * MAX_CONTACTS);
    for contacts in &scene.rings {
        for slot in 0..MAX_CONTACTS {
            let Some(c) = contacts.get(slot) else {
                slots.push(layout::GeneratingContact::zeroed());
                continue;
            };
            let f = &c.frame;
            let (phase_whole, phase_fraction) = split_count(c.phase_turns);
            let v = |a: [f64; 3]| [a[0] as f32, a[1] as f32, a[2] as f32];
            let ([offset_rho, offset_phi, offset_z], [radial_rho, radial_phi, radial_z]) =
                (v(f.offset), v(f.radial));
            let ([tangent_rho, tangent_phi, tangent_z], [axis_rho, axis_phi, axis_z]) =
                (v(f.tangent), v(f.axis));
            slots.push(layout::GeneratingContact {
                depth_mm: c.depth_mm as f32,
                radius_mm: f.radius_mm as f32,
                azimuth_rad: c.azimuth_rad as f32,
                phase_fraction,
                offset_rho,
                offset_phi,
                offset_z,
                phase_whole,
                radial_rho,
                radial_phi,
                radial_z,
                _padding0: 0.0,
                tangent_rho,
                tangent_phi,
                tangent_z,
                _padding1: 0.0,
                axis_rho,
                axis_phi,
                axis_z,
                _padding2: 0.0,
            });
        }
    }
    (rings, slots)
}
