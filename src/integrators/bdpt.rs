//! Host side of bidirectional path tracing: the strategy list, the sizes of its
//! per-pixel light-vertex buffer and of its strategy images, its render (passes in
//! bands, resolve), and the extra passes that record strategy images in groups. (The
//! kernel is glsl/bdpt.comp; the CPU mirror of its MIS weights is `bdpt_mis`.)
use crate::gpu::abi::*;
use crate::gpu::buffer::{memory_barrier, Buffer};
use crate::gpu_scene::GpuScene;
use crate::io::Image;
use crate::render::{add_film, band_rows, film_image, Passes, Prepared, RenderOutput, Renderer};
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::{bail, Result};
use ash::vk;

/// One BDPT strategy's share of the image: s light vertices, t camera vertices (the
/// camera included). `weighted` carries the MIS weight, so the weighted images of all
/// strategies sum to the BDPT image; `unweighted` is the strategy's own estimate.
pub struct StrategyImages {
    pub s: u32,
    pub t: u32,
    pub weighted: Image,
    pub unweighted: Image,
}

/// The (s,t) strategies of BDPT for paths of up to `max_scatter` scattering vertices, in
/// the order of the kernel's strategy buffer: by scattering vertices n = s + t - 2, then s.
pub fn bdpt_strategies(max_scatter: u32) -> Vec<(u32, u32)> {
    (0..=max_scatter)
        .flat_map(|n| (0..=n + 1).map(move |s| (s, n + 2 - s)))
        .collect()
}

/// Host memory lightpath allows for BDPT strategy images (RGB f32, two per strategy).
const STRATEGY_HOST_BUDGET: u64 = 8 << 30;

/// How many strategies' images (weighted and unweighted, vec4 per pixel) one storage
/// buffer of `range` bytes holds for a `width` × `height` image: all `count` of them
/// when they fit, else a group of them (the render then repeats its passes once per
/// group). 0 when `count` is 0. Errors when one strategy does not fit, or when all of
/// them would take more than STRATEGY_HOST_BUDGET on the host.
pub fn strategy_group_size(
    count: u64,
    width: u32,
    height: u32,
    range: u64,
    device: &str,
) -> Result<u32> {
    if count == 0 {
        return Ok(0);
    }
    let pixels = width as u64 * height as u64;
    let host = count * 2 * pixels * 12;
    if host > STRATEGY_HOST_BUDGET {
        bail!(
            "the images of {count} BDPT strategies at {width}x{height} would take {:.1} GiB of memory (at most {} GiB); use a smaller --size or --max-depth",
            host as f64 / (1u64 << 30) as f64,
            STRATEGY_HOST_BUDGET >> 30
        );
    }
    let per_strategy = 2 * pixels * 16;
    let group = (range / per_strategy).min(count).min(0xffff);
    if group == 0 {
        bail!(
            "one BDPT strategy's images at {width}x{height} need {per_strategy} bytes, more than {device}'s storage-buffer range ({range} bytes); use a smaller --size"
        );
    }
    Ok(group as u32)
}

/// Bytes per pixel of a BDPT pass's light-vertex buffer.
pub fn bdpt_vertex_bytes_per_pixel(max_scatter: u32) -> u64 {
    (max_scatter.max(2) - 1) as u64 * std::mem::size_of::<GpuPathVertex>() as u64
}

/// Largest device allocation lightpath makes for BDPT light vertices, whatever the
/// device's storage-buffer range.
pub(crate) const VERTEX_BUFFER_BUDGET: u64 = 1 << 30;

/// BDPT's bound on the scattering vertices of paths that get every strategy: maxdepth,
/// or BDPT_UNBOUNDED_DEPTH_CAP for -1 (longer paths then continue on the camera side).
pub fn bdpt_max_scatter(scene: &Scene) -> u32 {
    if scene.settings.max_depth < 0 {
        BDPT_UNBOUNDED_DEPTH_CAP
    } else {
        scene.settings.max_depth as u32
    }
}

/// SceneParams.bdpt.x: record the images of strategies first .. first + count (by
/// the kernel's index; count 0: none).
pub fn strategy_selection(first: u32, count: u32) -> u32 {
    (first << 16) | count
}

/// What the extra passes of `record_other_strategy_groups` render with: the first
/// render's buffers, passes and pass count.
pub(crate) struct StrategyGroupPass<'a> {
    pub gpu_scene: &'a GpuScene,
    pub strategy_film: &'a Buffer,
    pub passes: Passes<'a>,
    pub spp: u32,
}

impl Renderer {
    /// Render with BDPT: passes of glsl/bdpt.comp in bands whose light vertices fit the
    /// device, then (with `record_strategies`) the same passes once per further group
    /// of strategy images; image = (camera film + splat film) / spp.
    pub(crate) fn render_bdpt(
        &mut self,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        let kernel = "bdpt";
        let (width, height) = (scene.width, scene.height);
        let film_bytes = self.film_bytes(width, height)?;
        self.require_float_atomics("bdpt splats light-tracing samples")?;
        let limit = self.device.info.max_storage_buffer_range;
        let max_scatter = bdpt_max_scatter(scene);
        let vertex_bytes = bdpt_vertex_bytes_per_pixel(max_scatter);
        let vertex_limit = limit
            .min(VERTEX_BUFFER_BUDGET)
            .min(self.vertex_buffer_limit.unwrap_or(u64::MAX));
        let rows = band_rows(width, height, vertex_bytes, vertex_limit)?;
        let strategies = if self.record_strategies {
            bdpt_strategies(max_scatter)
        } else {
            Vec::new()
        };
        // Strategy images are recorded in groups that fit one storage buffer; each group
        // after the first re-renders the same samples (same seed, same passes).
        let strategy_group = strategy_group_size(
            strategies.len() as u64,
            width,
            height,
            limit.min(self.strategy_buffer_limit.unwrap_or(u64::MAX)),
            &self.device.info.name,
        )?;
        let strategy_bytes = strategy_group as u64 * 2 * film_bytes;
        let Prepared { gpu_scene, rq, .. } =
            self.prepare(scene, seed, strategy_selection(0, strategy_group), trace)?;
        let pipeline = trace.cpu("pipeline creation", || self.pass_pipeline(kernel))?;
        let (film, stats, splat, vertices, strategy_film) =
            trace.cpu("BDPT buffers", || -> Result<_> {
                Ok((
                    self.storage_buffer("film", film_bytes)?,
                    self.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
                    self.storage_buffer("splat film", film_bytes)?,
                    Buffer::device_local(
                        &self.device,
                        "BDPT light vertices",
                        (rows as u64 * width as u64 * vertex_bytes).max(16),
                        vk::BufferUsageFlags::STORAGE_BUFFER,
                    )?,
                    self.storage_buffer("strategy films", strategy_bytes.max(16))?,
                ))
            })?;
        let set = self.descriptor_set(
            &gpu_scene,
            &[
                (BINDING_FILM, &film),
                (BINDING_STATS, &stats),
                (BINDING_SPLAT, &splat),
                (BINDING_PATH_VERTICES, &vertices),
                (BINDING_STRATEGIES, &strategy_film),
            ],
            rq.as_ref(),
        )?;
        let params = PassParams { pass: [0, 0, 0, 1] };
        self.warm_up(pipeline, set, bytemuck::bytes_of(&params), trace)?;

        let passes = Passes {
            pipeline,
            set,
            kernel,
            width,
            height,
            band_rows: rows,
        };
        // image = (camera film + splat film) / spp
        let resolve = |done: u32| -> Result<Image> {
            let (f, sp) = (film.download(film_bytes)?, splat.download(film_bytes)?);
            let inv = 1.0 / done as f32;
            let mut image = film_image(bytemuck::cast_slice(&f), width, height, inv);
            add_film(&mut image, bytemuck::cast_slice(&sp), inv);
            Ok(image)
        };
        let (dispatch_seconds, spp) =
            self.dispatch_passes(passes, 0, scene.settings.spp.max(1), Some(&resolve), trace)?;

        let (film_data, stat, splat_data, strategy_data) =
            trace.cpu("readback", || -> Result<_> {
                Ok((
                    film.download(film_bytes)?,
                    self.read_stats(&stats, kernel)?,
                    splat.download(film_bytes)?,
                    if strategies.is_empty() {
                        None
                    } else {
                        Some(strategy_film.download(strategy_bytes)?)
                    },
                ))
            })?;
        let mut strategy_data: Vec<Vec<u8>> = strategy_data.into_iter().collect();
        // (An interrupted render keeps the strategy images it has.)
        if !strategies.is_empty() && !self.interrupted() {
            strategy_data.extend(self.record_other_strategy_groups(
                StrategyGroupPass {
                    gpu_scene: &gpu_scene,
                    strategy_film: &strategy_film,
                    passes,
                    spp,
                },
                strategy_group,
                strategy_group,
                strategies.len() as u32,
                trace,
            )?);
        }
        let film: &[[f32; 4]] = bytemuck::cast_slice(&film_data);
        let inv = 1.0 / spp.max(1) as f32;
        let to_image = |data: &[[f32; 4]]| film_image(data, width, height, inv);
        // The image is camera film / spp + splat film / spp.
        let mut image = to_image(film);
        add_film(&mut image, bytemuck::cast_slice(&splat_data), inv);
        let npix = (width * height) as usize;
        let strategies = strategy_data
            .iter()
            .flat_map(|data| {
                let all: &[[f32; 4]] = bytemuck::cast_slice(data);
                all.chunks_exact(2 * npix)
            })
            .zip(&strategies)
            .map(|(both, &(s, t))| StrategyImages {
                s,
                t,
                weighted: to_image(&both[..npix]),
                unweighted: to_image(&both[npix..]),
            })
            .collect();
        let rays = film.iter().map(|p| p[3] as f64).sum();
        Ok(RenderOutput {
            image,
            nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
            rays,
            samples_per_pixel: spp,
            dispatch_seconds,
            backend: self.backend(),
            strategies,
            mmlt: None,
            interrupted: self.interrupt_signal(),
        })
    }

    /// After a render that recorded the first `first` strategies: the same passes
    /// again (same seed and pass indices, so the same samples) once per further group
    /// of at most `group` strategies, until all `total` are recorded. Returns each
    /// group's strategy-film bytes. The film and splat film, which these passes also
    /// add to, were read back before.
    pub(crate) fn record_other_strategy_groups(
        &mut self,
        p: StrategyGroupPass,
        first: u32,
        group: u32,
        total: u32,
        trace: &mut Trace,
    ) -> Result<Vec<Vec<u8>>> {
        let film_bytes = p.passes.width as u64 * p.passes.height as u64 * 16;
        let mut out = Vec::new();
        let mut first = first;
        while first < total {
            let count = group.min(total - first);
            let mut params = p.gpu_scene.params;
            params.bdpt[0] = strategy_selection(first, count);
            let device = self.device.clone();
            device.run_commands("selecting the next group of BDPT strategies", |cmd| {
                let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
                let transfer = vk::PipelineStageFlags::TRANSFER;
                let shader_access = vk::AccessFlags::SHADER_READ
                    | vk::AccessFlags::SHADER_WRITE
                    | vk::AccessFlags::UNIFORM_READ;
                memory_barrier(
                    &device,
                    cmd,
                    (compute, shader_access),
                    (transfer, vk::AccessFlags::TRANSFER_WRITE),
                );
                unsafe {
                    device.raw.cmd_update_buffer(
                        cmd,
                        p.gpu_scene.scene_params.raw,
                        0,
                        bytemuck::bytes_of(&params),
                    );
                    device
                        .raw
                        .cmd_fill_buffer(cmd, p.strategy_film.raw, 0, vk::WHOLE_SIZE, 0);
                }
                memory_barrier(
                    &device,
                    cmd,
                    (transfer, vk::AccessFlags::TRANSFER_WRITE),
                    (compute, shader_access),
                );
            })?;
            // Exactly the first render's passes, whatever the time limit.
            let time_limit = self.time_limit.take();
            let again = self.dispatch_passes(p.passes, 0, p.spp, None, trace);
            self.time_limit = time_limit;
            again?;
            if self.interrupted() {
                // This group's passes were cut short: its images are left out.
                break;
            }
            out.push(trace.cpu("readback", || {
                p.strategy_film.download(count as u64 * 2 * film_bytes)
            })?);
            first += count;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bdpt_strategy_list_counts_every_s_t_pair() {
        let st = bdpt_strategies(5);
        assert_eq!(st.len(), 6 * 9 / 2);
        assert_eq!(&st[..5], &[(0, 2), (1, 1), (0, 3), (1, 2), (2, 1)]);
        assert!(st.iter().all(|&(s, t)| t >= 1 && s + t <= 7));
        // The kernel's index n(n+3)/2 + s.
        for (i, &(s, t)) in st.iter().enumerate() {
            let n = s + t - 2;
            assert_eq!(i as u32, n * (n + 3) / 2 + s);
        }
    }

    #[test]
    fn strategy_images_are_grouped_to_fit_the_storage_buffer_range() {
        let lavapipe = 128 << 20;
        // 480x480 at maxdepth 5: 27 strategies of 2 × 3.7 MB; 18 fit in 128 MiB.
        assert_eq!(
            strategy_group_size(27, 480, 480, lavapipe, "d").unwrap(),
            18
        );
        // All of them when they fit, none when none are asked for.
        assert_eq!(strategy_group_size(27, 64, 64, lavapipe, "d").unwrap(), 27);
        assert_eq!(
            strategy_group_size(0, 4096, 4096, lavapipe, "d").unwrap(),
            0
        );
        // 1080p at maxdepth 10: 77 strategies, 2 per buffer.
        let g = strategy_group_size(77, 1920, 1080, lavapipe, "d").unwrap();
        assert_eq!(g, 2);
        assert!(g as u64 * 2 * 1920 * 1080 * 16 <= lavapipe);
        // One strategy larger than the range, or too many images for the host: errors.
        let e = strategy_group_size(3, 4096, 4096, lavapipe, "d").unwrap_err();
        assert!(e.to_string().contains("storage-buffer range"), "{e}");
        let e = strategy_group_size(594, 1920, 1080, 4 << 30, "d").unwrap_err();
        assert!(e.to_string().contains("GiB of memory"), "{e}");
    }
}
