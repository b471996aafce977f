//! `shellbake view`: a winit window around the same [`GltfRenderer`] the headless paths use.
//!
//! Controls: left-drag orbits, the wheel zooms (distance in bounding radii), `↑`/`↓` (or `]`/`[`)
//! step the layers shown (`layers ≤ k`), `L` steps the `MSFT_lod` level when the file has LODs,
//! `R` resets the camera, `Esc` quits. The title shows the file, the frame time (GPU timestamps
//! when the adapter has them, CPU frame-to-frame time otherwise), the triangles and draw calls
//! per frame, the layer limit and the LOD. A file with animations (shellbake's `wind`) plays
//! them, looping, from the moment the window opens.
//!
//! `--screenshot PATH --frames N` renders N frames to the window surface and saves the last one
//! by copying the **surface texture** itself (configured with `COPY_SRC` where the surface allows
//! it) before presenting, then exits: the smoke test sees what the window path drew, not a
//! separate headless render. Where the surface cannot be copied, the viewer says so and exits
//! with an error rather than quietly falling back to the headless path.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use super::camera::{Camera, Orbit};
use super::glb::Asset;
use super::gltf::GltfRenderer;
use super::gpu::{self, Gpu, Light, Result, ViewError};

/// Options of the window.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    pub title: String,
    pub size: (u32, u32),
    pub orbit: Orbit,
    /// Save the last of `frames` frames here and exit.
    pub screenshot: Option<PathBuf>,
    pub frames: u32,
}

struct Running {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    depth: wgpu::TextureView,
    gpu: Gpu,
    renderer: GltfRenderer,
}

struct App {
    options: ViewOptions,
    asset: Option<Asset>,
    running: Option<Running>,
    orbit: Orbit,
    dragging: bool,
    cursor: Option<(f64, f64)>,
    layer_limit: Option<usize>,
    /// A level forced with `L`, or `None`: each chunk's level by distance.
    lod: Option<usize>,
    frames: u32,
    last_frame: Option<Instant>,
    /// When the animations started.
    clock: Instant,
    frame_ms: f64,
    error: Option<ViewError>,
}

/// Opens the window on `asset` and runs until it is closed (or the screenshot is taken).
pub fn run(asset: Asset, options: ViewOptions) -> Result<()> {
    let event_loop = EventLoop::new().map_err(|e| ViewError::Window(e.to_string()))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App {
        orbit: options.orbit,
        options,
        asset: Some(asset),
        running: None,
        dragging: false,
        cursor: None,
        layer_limit: None,
        lod: None,
        frames: 0,
        last_frame: None,
        clock: Instant::now(),
        frame_ms: 0.0,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| ViewError::Window(e.to_string()))?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

impl App {
    fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let (w, h) = self.options.size;
        let attrs = Window::default_attributes()
            .with_title(self.options.title.clone())
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h))
            .with_resizable(self.options.screenshot.is_none());
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .map_err(|e| ViewError::Window(e.to_string()))?,
        );
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| ViewError::Window(e.to_string()))?;
        let gpu = Gpu::with_instance(instance, Some(&surface))?;
        let caps = surface.get_capabilities(&gpu.adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| f.is_srgb())
            .unwrap_or(caps.formats[0]);
        let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
        if self.options.screenshot.is_some() {
            if !caps.usages.contains(wgpu::TextureUsages::COPY_SRC) {
                return Err(ViewError::Window(
                    "this surface cannot be copied from; no screenshot possible".into(),
                ));
            }
            usage |= wgpu::TextureUsages::COPY_SRC;
        }
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage,
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::AutoNoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps.alpha_modes[0],
            view_formats: vec![],
            color_space: Default::default(),
        };
        surface.configure(&gpu.device, &config);
        let depth =
            gpu::depth_texture(&gpu, config.width, config.height).create_view(&Default::default());
        let renderer = GltfRenderer::new(&gpu, self.asset.take().expect("started once"))?;
        self.running = Some(Running {
            window,
            surface,
            config,
            depth,
            gpu,
            renderer,
        });
        Ok(())
    }

    fn title(&self) -> String {
        let Some(r) = &self.running else {
            return String::new();
        };
        let layers = r.renderer.layer_count();
        let shown = self.layer_limit.map_or(layers, |k| (k + 1).min(layers));
        let lod = if r.renderer.lod_levels() > 0 {
            let picks = r.renderer.lod_picks();
            match self.lod {
                Some(k) => format!(" — LOD {k}/{} (forced)", r.renderer.lod_levels()),
                None => format!(
                    " — LOD by distance: {} chunk(s) at levels {}..{}",
                    picks.len(),
                    picks.iter().min().unwrap_or(&0),
                    picks.iter().max().unwrap_or(&0)
                ),
            }
        } else {
            String::new()
        };
        format!(
            "{} — {:.2} ms — {} triangles, {} draws — layers {shown}/{layers}{lod}",
            self.options.title,
            self.frame_ms,
            r.renderer.triangles(),
            r.renderer.draw_calls()
        )
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let Some(r) = &mut self.running else {
            return Ok(());
        };
        let frame = match r.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                r.surface.configure(&r.gpu.device, &r.config);
                return Ok(());
            }
            _ => return Ok(()),
        };
        let view = frame.texture.create_view(&Default::default());
        let aspect = r.config.width as f64 / r.config.height as f64;
        let camera = Camera::frame(r.renderer.bounds, self.orbit, aspect);
        r.renderer.set_layer_limit(self.layer_limit);
        if r.renderer.animated() {
            let time = self.clock.elapsed().as_secs_f32();
            r.renderer.set_time(&r.gpu, Some(time))?;
        }
        r.renderer
            .prepare(&r.gpu, &camera, &Light::default(), r.config.format);
        let timing = r.gpu.time_passes(1, |encoder, ts| {
            let mut pass = gpu::begin_pass(encoder, &view, &r.depth, ts);
            r.renderer.record(&mut pass);
        });
        let now = Instant::now();
        self.frame_ms = timing.gpu_ms.unwrap_or_else(|| {
            self.last_frame.map_or(timing.wall_ms, |t| {
                now.duration_since(t).as_secs_f64() * 1e3
            })
        });
        self.last_frame = Some(now);
        self.frames += 1;
        let shot = self
            .options
            .screenshot
            .clone()
            .filter(|_| self.frames >= self.options.frames.max(1));
        if let Some(path) = &shot {
            let image = r.gpu.read_texture(&frame.texture);
            gpu::save_png(&image, path)?;
        }
        r.window.pre_present_notify();
        r.gpu.queue.present(frame);
        let title = self.title();
        if let Some(r) = &self.running {
            r.window.set_title(&title);
        }
        if shot.is_some() {
            event_loop.exit();
        }
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: ViewError) {
        self.error = Some(e);
        event_loop.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_none() && self.asset.is_some() {
            if let Err(e) = self.start(event_loop) {
                self.fail(event_loop, e);
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(r) = &mut self.running {
                    r.config.width = size.width.max(1);
                    r.config.height = size.height.max(1);
                    r.surface.configure(&r.gpu.device, &r.config);
                    r.depth = gpu::depth_texture(&r.gpu, r.config.width, r.config.height)
                        .create_view(&Default::default());
                }
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.dragging = state == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (true, Some((x, y))) = (self.dragging, self.cursor) {
                    self.orbit.yaw_deg -= (position.x - x) * 0.4;
                    self.orbit.pitch_deg =
                        (self.orbit.pitch_deg + (position.y - y) * 0.4).clamp(-89.0, 89.0);
                }
                self.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y as f64,
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                let aspect = self
                    .running
                    .as_ref()
                    .map_or(1.0, |r| r.config.width as f64 / r.config.height as f64);
                let fit = self.running.as_ref().map_or(3.0, |r| {
                    let c = Camera::frame(
                        r.renderer.bounds,
                        Orbit {
                            distance: None,
                            ..self.orbit
                        },
                        aspect,
                    );
                    (c.eye - c.target).length() / r.renderer.bounds.radius
                });
                let d = self.orbit.distance.unwrap_or(fit);
                self.orbit.distance = Some((d * 0.9f64.powf(steps)).clamp(0.05, 100.0));
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                let layers = self
                    .running
                    .as_ref()
                    .map_or(1, |r| r.renderer.layer_count().max(1));
                let current = self.layer_limit.unwrap_or(layers - 1);
                match event.logical_key.as_ref() {
                    Key::Named(NamedKey::Escape) => event_loop.exit(),
                    Key::Named(NamedKey::ArrowUp) | Key::Character("]") => {
                        self.layer_limit = (current + 1 < layers - 1).then_some(current + 1);
                    }
                    Key::Named(NamedKey::ArrowDown) | Key::Character("[") => {
                        self.layer_limit = Some(current.saturating_sub(1));
                    }
                    Key::Character("l") | Key::Character("L") => {
                        if let Some(r) = &mut self.running {
                            let levels = r.renderer.lod_levels();
                            // by distance → 0 → 1 → … → last → by distance
                            self.lod = match self.lod {
                                None if levels > 0 => Some(0),
                                Some(k) if k < levels => Some(k + 1),
                                _ => None,
                            };
                            if let Err(e) = r.renderer.set_lod(&r.gpu, self.lod) {
                                self.fail(event_loop, e);
                            }
                        }
                    }
                    Key::Character("r") | Key::Character("R") => {
                        self.orbit = self.options.orbit;
                        self.layer_limit = None;
                    }
                    _ => {}
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(r) = &self.running {
            r.window.request_redraw();
        }
    }
}
