//! The GPU engine: `shaders/turning.wgsl`, `generating.wgsl` and `milling.wgsl` (each
//! after `shared.wgsl`) through wgpu. Geometry is prepared by the scenes in f64 and
//! uploaded as hi + lo f32 pairs or as small local-frame differences (`inputs`); the
//! kernels work in sample-relative coordinates so f32 resolves sub-nanometre depths.
//! Grids whose result does not fit one storage binding are processed in tiles.

use super::generating_scene::GeneratingScene;
use super::milling_scene::MillingScene;
use super::scene::TurningScene;
use super::{EngineError, EngineInfo, Progress, RemovalEngine, Scene};
use crate::field::DexelField;
use bytemuck::Pod;
use wgpu::util::DeviceExt;

/// The kernel sources as compiled: the shared declarations, then the kernel (tests
/// validate them with naga).
pub const TURNING_SHADER: &str = concat!(
    include_str!("../../../shaders/shared.wgsl"),
    include_str!("../../../shaders/turning.wgsl")
);
pub const GENERATING_SHADER: &str = concat!(
    include_str!("../../../shaders/shared.wgsl"),
    include_str!("../../../shaders/generating.wgsl")
);
pub const MILLING_SHADER: &str = concat!(
    include_str!("../../../shaders/shared.wgsl"),
    include_str!("../../../shaders/milling.wgsl")
);

/// Threads per workgroup (`@workgroup_size` in the shader).
const WORKGROUP_SIZE: u32 = 64;
/// Samples per dispatch at most, so progress moves and no dispatch runs for minutes: on
/// a software adapter (lavapipe), and on a GPU, where a larger tile costs fewer
/// submissions (the target job on an H100: removal 0.47 s in 2²² tiles, 0.37 s in 2²⁴).
const MAX_TILE_SAMPLES_SOFTWARE: u64 = 1 << 22;
const MAX_TILE_SAMPLES_GPU: u64 = 1 << 24;
/// Tiles queued on the device at once (the host reads one while the next runs).
const TILES_IN_FLIGHT: u64 = 2;
/// Most workgroups along one dispatch dimension (WebGPU's limit).
const MAX_GROUPS_PER_DIMENSION: u64 = 65_535;

pub mod inputs;
pub mod layout;

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

/// A compute pipeline with the bindings every kernel has: 0 the uniform parameters,
/// 1..=n read-only inputs, n + 1 the dexel output.
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
    /// The milling kernel, compiled per (tool kind, stamp mode) when first needed.
    milling: std::collections::HashMap<(u32, u32), Kernel>,
    info: EngineInfo,
    max_binding_bytes: u64,
    /// Caps the samples per tile below what the adapter allows (tests use it to force tiling).
    pub max_tile_samples: u64,
}

impl GpuEngine {
    /// Whether the adapter is a software rasteriser running on the host's cores (such as
    /// Mesa lavapipe), not a GPU.
    pub fn is_software(&self) -> bool {
        self.info.device_type == format!("{:?}", wgpu::DeviceType::Cpu)
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

        let name = &adapter_info.name;
        let turning = build_kernel(&device, "remove_turning", TURNING_SHADER, 3, &[], name)?;
        let generating = build_kernel(
            &device,
            "remove_generating",
            GENERATING_SHADER,
            3,
            &[],
            name,
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
            milling: std::collections::HashMap::new(),
            info,
            max_binding_bytes: limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size),
            max_tile_samples: if adapter_info.device_type == wgpu::DeviceType::Cpu {
                MAX_TILE_SAMPLES_SOFTWARE
            } else {
                MAX_TILE_SAMPLES_GPU
            },
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
}

/// Compiles one kernel; validation errors come back as values, not wgpu's default panic.
fn build_kernel(
    device: &wgpu::Device,
    entry: &'static str,
    source: &str,
    inputs: u32,
    constants: &[(&str, f64)],
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
    let uniform = wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let entries: Vec<wgpu::BindGroupLayoutEntry> = std::iter::once(uniform)
        .chain((1..=inputs).map(|binding| storage(binding, true)))
        .chain(std::iter::once(storage(inputs + 1, false)))
        .collect();
    let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(entry),
        entries: &entries,
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
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            ..Default::default()
        },
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

impl RemovalEngine for GpuEngine {
    fn info(&self) -> EngineInfo {
        self.info.clone()
    }

    fn remove(&mut self, scene: &Scene, progress: Progress<'_>) -> Result<DexelField, EngineError> {
        match scene {
            Scene::Turning(scene) => self.remove_turning(scene, progress),
            Scene::Generating(scene) => self.remove_generating(scene, progress),
            Scene::Milling(scene) => self.remove_milling(scene, progress),
        }
    }
}

impl GpuEngine {
    fn remove_turning(
        &mut self,
        scene: &TurningScene,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        let (rings, poses, deviation) = inputs::turning(scene);
        let buffers = [
            self.upload("rings", &rings)?,
            self.upload("poses", &poses)?,
            self.upload("edge deviation", &deviation)?,
        ];
        self.dispatch(
            &self.turning,
            &buffers,
            scene.grid.sample_count() as u64,
            &|offset, count, width| inputs::turning_params(scene, offset, count, width),
            progress,
        )
    }

    fn remove_generating(
        &mut self,
        scene: &GeneratingScene,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        let (rings, contacts, phases) = inputs::generating(scene);
        let buffers = [
            self.upload("generating rings", &rings)?,
            self.upload("contacts", &contacts)?,
            self.upload("azimuth phases", &phases)?,
        ];
        self.dispatch(
            &self.generating,
            &buffers,
            scene.grid.sample_count() as u64,
            &|offset, count, width| Ok(inputs::generating_params(scene, offset, count, width)),
            progress,
        )
    }

    fn remove_milling(
        &mut self,
        scene: &MillingScene,
        progress: Progress<'_>,
    ) -> Result<DexelField, EngineError> {
        let variant = inputs::milling_variant(scene);
        if !self.milling.contains_key(&variant) {
            let constants = [
                ("TOOL_KIND", variant.0 as f64),
                ("STAMP_MODE", variant.1 as f64),
            ];
            let kernel = build_kernel(
                &self.device,
                "remove_milling",
                MILLING_SHADER,
                7,
                &constants,
                &self.info.adapter,
            )?;
            self.milling.insert(variant, kernel);
        }
        let m = inputs::milling(scene);
        let buffers = [
            self.upload("milling rings", &m.rings)?,
            self.upload("milling rows", &m.rows)?,
            self.upload("path nodes", &m.nodes)?,
            self.upload("passes", &m.passes)?,
            self.upload("bin cells", &m.cell_start)?,
            self.upload("node runs", &m.runs)?,
            self.upload("teeth", &m.teeth)?,
        ];
        self.dispatch(
            &self.milling[&variant],
            &buffers,
            scene.grid.sample_count() as u64,
            &|offset, count, width| Ok(inputs::milling_params(scene, offset, count, width)),
            progress,
        )
    }

    /// Runs `kernel` over every sample, in tiles that fit one storage binding, with
    /// [`TILES_IN_FLIGHT`] tiles queued: while the host reads tile k back, the device
    /// already runs tile k + 1 (each tile has its own output, read-back and parameter
    /// buffers). Results arrive in tile order.
    fn dispatch<P: Pod>(
        &self,
        kernel: &Kernel,
        inputs: &[wgpu::Buffer],
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
        let slots: Vec<TileSlot> = (0..sample_count.div_ceil(tile_samples).min(TILES_IN_FLIGHT))
            .map(|_| self.tile_slot::<P>(kernel, inputs, tile_samples * dexel_bytes))
            .collect();
        // Zeroed by the allocator (fresh pages), so the first touch of each page falls
        // to the parallel read-back, not to a serial fill here.
        let mut field = DexelField {
            depth_mm: vec![0.0; sample_count as usize],
            pass: vec![0; sample_count as usize],
        };
        let mut in_flight = std::collections::VecDeque::<InFlight>::new();
        let mut offset = 0u64;
        while offset < sample_count {
            if in_flight.len() == slots.len()
                && let Some(done) = in_flight.pop_front()
            {
                self.read_tile(&slots[done.slot], done, &mut field, sample_count, progress)?;
            }
            let count = tile_samples.min(sample_count - offset);
            let slot = (offset / tile_samples) as usize % slots.len();
            let tile = params(offset, count, dispatch_width(count))?;
            let submission = self.submit_tile(kernel, &slots[slot], &tile, count)?;
            in_flight.push_back(InFlight {
                slot,
                offset,
                count,
                submission,
            });
            offset += count;
        }
        for done in in_flight {
            self.read_tile(&slots[done.slot], done, &mut field, sample_count, progress)?;
        }
        Ok(field)
    }

    /// One tile's buffers, bound to `kernel` with its `inputs`.
    fn tile_slot<P: Pod>(&self, kernel: &Kernel, inputs: &[wgpu::Buffer], bytes: u64) -> TileSlot {
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let output = buffer("dexels", bytes, U::STORAGE | U::COPY_SRC);
        let staging = buffer("dexels read-back", bytes, U::MAP_READ | U::COPY_DST);
        let params = buffer(
            "params",
            std::mem::size_of::<P>() as u64,
            U::UNIFORM | U::COPY_DST,
        );
        let buffers: Vec<&wgpu::Buffer> = std::iter::once(&params)
            .chain(inputs)
            .chain(std::iter::once(&output))
            .collect();
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
        TileSlot {
            output,
            staging,
            params,
            bind_group,
        }
    }

    /// Queues one tile of `count` samples with parameters `tile` on `slot`: the kernel,
    /// then the copy of its output to the read-back buffer.
    fn submit_tile<P: Pod>(
        &self,
        kernel: &Kernel,
        slot: &TileSlot,
        tile: &P,
        count: u64,
    ) -> Result<wgpu::SubmissionIndex, EngineError> {
        let (groups_x, groups_y) = workgroup_grid(count);
        let out_of_memory = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.queue
            .write_buffer(&slot.params, 0, bytemuck::bytes_of(tile));
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
            compute.set_bind_group(0, &slot.bind_group, &[]);
            compute.dispatch_workgroups(groups_x, groups_y, 1);
        }
        let bytes = count * std::mem::size_of::<layout::Dexel>() as u64;
        encoder.copy_buffer_to_buffer(&slot.output, 0, &slot.staging, 0, bytes);
        let submission = self.queue.submit([encoder.finish()]);
        for (scope, what) in [
            (validation, "GPU dispatch failed"),
            (out_of_memory, "out of GPU memory"),
        ] {
            if let Some(err) = pollster::block_on(scope.pop()) {
                return Err(EngineError(format!("{what}: {err}")));
            }
        }
        Ok(submission)
    }

    /// Waits for the tile `done` (the oldest in flight) and writes its samples into
    /// `field` at the tile's offset, straight from the mapped read-back buffer, in
    /// parallel stretches.
    fn read_tile(
        &self,
        slot: &TileSlot,
        done: InFlight,
        field: &mut DexelField,
        sample_count: u64,
        progress: Progress<'_>,
    ) -> Result<(), EngineError> {
        let staging = &slot.staging;
        let bytes = done.count * std::mem::size_of::<layout::Dexel>() as u64;
        let slice = staging.slice(..bytes);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |result| {
            let _ = sender.send(result);
        });
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(done.submission),
                timeout: None,
            })
            .map_err(|err| EngineError(format!("GPU wait failed: {err}")))?;
        receiver
            .recv()
            .map_err(|_| EngineError("GPU read-back was dropped".into()))?
            .map_err(|err| EngineError(format!("GPU read-back failed: {err}")))?;
        let view = slice
            .get_mapped_range()
            .map_err(|err| EngineError(format!("GPU read-back mapping failed: {err:?}")))?;
        let dexels: &[layout::Dexel] = bytemuck::cast_slice(&view);
        let tile = done.offset as usize..(done.offset + done.count) as usize;
        convert_dexels(
            dexels,
            &mut field.depth_mm[tile.clone()],
            &mut field.pass[tile.clone()],
        );
        drop(view);
        staging.unmap();
        progress(tile.end as u64, sample_count);
        Ok(())
    }
}

/// One tile's device buffers and their binding.
struct TileSlot {
    output: wgpu::Buffer,
    staging: wgpu::Buffer,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

/// Splits f32 dexels into the field's f64 depths and pass ids, in parallel stretches.
fn convert_dexels(dexels: &[layout::Dexel], depth_mm: &mut [f64], pass: &mut [u32]) {
    use rayon::prelude::*;
    const STRETCH: usize = 1 << 16;
    dexels
        .par_chunks(STRETCH)
        .zip(depth_mm.par_chunks_mut(STRETCH))
        .zip(pass.par_chunks_mut(STRETCH))
        .for_each(|((from, depth), pass)| {
            for ((d, depth), pass) in from.iter().zip(depth).zip(pass) {
                *depth = d.depth_mm as f64;
                *pass = d.pass_id;
            }
        });
}

/// A tile queued and not yet read back.
struct InFlight {
    slot: usize,
    offset: u64,
    count: u64,
    submission: wgpu::SubmissionIndex,
}

/// Workgroups (x, y) for `count` samples: as few rows as the per-dimension limit allows
/// and the groups spread evenly over them, so that at most one group per row idles
/// (not a second row of 65 535 for one sample more than a row holds).
fn workgroup_grid(count: u64) -> (u32, u32) {
    let groups = count.div_ceil(WORKGROUP_SIZE as u64).max(1);
    let rows = groups.div_ceil(MAX_GROUPS_PER_DIMENSION);
    (groups.div_ceil(rows) as u32, rows as u32)
}

/// Samples per row of the dispatch grid for `count` samples (the kernels' index is
/// x + y · width).
fn dispatch_width(count: u64) -> u32 {
    workgroup_grid(count).0 * WORKGROUP_SIZE
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workgroup_grid_covers_every_sample_and_idles_under_a_group_per_row() {
        for count in [
            1,
            63,
            64,
            65,
            4_194_304,
            64 * 65_535,
            64 * 65_535 + 1,
            1 << 31,
        ] {
            let (x, y) = workgroup_grid(count);
            let groups = count.div_ceil(64);
            assert!(x as u64 <= MAX_GROUPS_PER_DIMENSION, "{count}: {x}");
            assert!(x as u64 * y as u64 >= groups, "{count}: {x} × {y}");
            assert!(
                x as u64 * y as u64 - groups < y as u64,
                "{count}: {x} × {y}"
            );
        }
        // 2²² samples: 65 536 groups in two rows of 32 768, not 65 535 + 65 535.
        assert_eq!(workgroup_grid(1 << 22), (32_768, 2));
    }
}
