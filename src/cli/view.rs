//! The binary's flags for the viewer commands (`render`, `view`, `verify`, `bench`): clap
//! structs close to the flags, each mapped onto the library's plain option structs
//! (`shellbake::view::cli`) in one `into_args`. This file belongs to the binary, not to the
//! library, which has no CLI types.

use std::path::PathBuf;

use clap::Args;
use shellbake::view::camera::NamedView;
use shellbake::view::cli::{self as view, parse_size};

use crate::named;

/// Camera flags shared by `render` and `view`.
#[derive(Args, Clone, Debug)]
pub struct CameraFlags {
    /// Named camera; --yaw/--pitch/--distance override its parts.
    #[arg(long, default_value = "front", value_parser = named(&NamedView::ALL, |v| v.name()))]
    view: NamedView,
    /// Orbit angle about +Y in degrees (0 looks from +Z).
    #[arg(long, allow_hyphen_values = true)]
    yaw: Option<f64>,
    /// Elevation in degrees, -89..89.
    #[arg(long, allow_hyphen_values = true)]
    pitch: Option<f64>,
    /// Eye distance in multiples of the bounding radius [default: the view's, or fit].
    #[arg(long)]
    distance: Option<f64>,
}

impl CameraFlags {
    fn into_args(self) -> view::CameraArgs {
        view::CameraArgs {
            view: self.view,
            yaw: self.yaw,
            pitch: self.pitch,
            distance: self.distance,
        }
    }
}

/// `shellbake render`.
#[derive(Args, Clone, Debug)]
pub struct RenderFlags {
    /// Baked GLB to draw.
    input: PathBuf,
    /// Output PNG.
    #[arg(short, long)]
    output: PathBuf,
    /// Picture size.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    #[command(flatten)]
    camera: CameraFlags,
    /// Draw the file's animations (the `wind` effect, a skinned input's clip) at this time,
    /// in seconds.
    #[arg(long)]
    time: Option<f32>,
    /// The animation clip to play (by name) [default: the file's first].
    #[arg(long)]
    clip: Option<String>,
    /// Draw the file this many times and print the mean GPU time of a frame, the CPU time to
    /// record and submit it, the triangles and the draw calls (as `bench` times a bake).
    #[arg(long, default_value_t = 1)]
    frames: u32,
}

impl RenderFlags {
    pub fn into_args(self) -> view::RenderArgs {
        view::RenderArgs {
            input: self.input,
            output: self.output,
            size: self.size,
            camera: self.camera.into_args(),
            time: self.time,
            clip: self.clip,
            frames: self.frames,
        }
    }
}

/// `shellbake view`.
#[derive(Args, Clone, Debug)]
pub struct ViewFlags {
    /// Baked GLB to open.
    input: PathBuf,
    /// Window size.
    #[arg(long, default_value = "1024x768", value_parser = parse_size)]
    size: (u32, u32),
    #[command(flatten)]
    camera: CameraFlags,
    /// Render --frames frames, save the last one from the window surface to this PNG, exit.
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Frames to render before the screenshot.
    #[arg(long, default_value_t = 3)]
    frames: u32,
    /// The animation clip to play (by name) [default: the file's first].
    #[arg(long)]
    clip: Option<String>,
}

impl ViewFlags {
    pub fn into_args(self) -> view::ViewArgs {
        view::ViewArgs {
            input: self.input,
            size: self.size,
            camera: self.camera.into_args(),
            screenshot: self.screenshot,
            frames: self.frames,
            clip: self.clip,
        }
    }
}

/// `shellbake verify` flags besides the bake flags.
#[derive(Args, Clone, Debug)]
pub struct VerifyFlags {
    /// Folder for the reference, baked and difference pictures.
    #[arg(long, default_value = "out/verify")]
    out_dir: PathBuf,
    /// Side of the square pictures.
    #[arg(long, default_value_t = shellbake::view::verify::DEFAULT_SIZE)]
    size: u32,
    /// Also compare at these animation times, seconds (comma-separated; the `wind` effect, a
    /// skinned input's clips) [default: a quarter and three quarters of the wind's period when a
    /// surface asks for it, and of a skinned input's longest clip].
    #[arg(long, value_delimiter = ',')]
    time: Vec<f32>,
    /// A skinned input's animation clip to compare (by name) [default: the first].
    #[arg(long)]
    clip: Option<String>,
}

impl VerifyFlags {
    /// The clip `--clip` names.
    pub fn clip(&self) -> Option<&str> {
        self.clip.as_deref()
    }

    pub fn into_args(self) -> view::VerifyArgs {
        view::VerifyArgs {
            out_dir: self.out_dir,
            size: self.size,
            times: self.time,
        }
    }
}

/// `shellbake bench` flags besides the bake flags.
#[derive(Args, Clone, Debug)]
pub struct BenchFlags {
    /// Frames drawn per measurement (the mean is reported).
    #[arg(long, default_value_t = 200)]
    frames: u32,
    /// Picture size.
    #[arg(long, default_value = "1920x1080", value_parser = parse_size)]
    size: (u32, u32),
    /// Write the figures as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Save each camera's picture of the reference and of each bake (bake0: no LOD, no cull;
    /// bake1: cull; bake2: LOD + cull) in this folder.
    #[arg(long)]
    pictures: Option<PathBuf>,
    /// A skinned input's animation clip (by name) [default: the first].
    #[arg(long)]
    clip: Option<String>,
}

impl BenchFlags {
    /// The clip `--clip` names.
    pub fn clip(&self) -> Option<&str> {
        self.clip.as_deref()
    }

    pub fn into_args(self) -> view::BenchArgs {
        view::BenchArgs {
            frames: self.frames,
            size: self.size,
            json: self.json,
            pictures: self.pictures,
        }
    }
}
