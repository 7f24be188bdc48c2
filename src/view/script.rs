//! Scripted viewer sessions: one action a line, parsed whole before the first frame so a typo on
//! the last line is refused before anything renders.

use crate::job::{FocalSurfaceSpec, FocusPointSpec};
use crate::limits::MAX_VIEW_FRAMES;
use crate::model::{AberrationScale, ModelKind};
use crate::render::focal_surface::DEFAULT_BETA;
use std::path::{Path, PathBuf};

/// One thing a script (or a key, a click or a dropped file in the window) asks the viewer to do.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Samples per pixel rendered each frame.
    SppPerFrame(u32),
    /// Focus on the surface under this pixel of the render.
    Click([u32; 2]),
    FNumber(f64),
    /// Focus on the plane this far in front of the first vertex (mm).
    Focus(f64),
    /// Pull focus from one distance to another (mm) over this many frames, one frame at each
    /// step, the steps even in dioptres (as the film moves).
    FocusPull {
        from_mm: f64,
        to_mm: f64,
        frames: u32,
    },
    /// Focus per pixel on a focal surface through these focus points (seed 004); None returns
    /// to the one focused plane the surface's centre was on.
    FocalSurface(Option<FocalSurfaceSpec>),
    /// Add a focus point (the surface under this pixel, or a distance / defocus) to the focal
    /// surface, starting one at the current focus's plane if there is none.
    FocusPoint(FocusPointSpec),
    /// The aperture stop's shape: its blades (count, rotation in degrees, curvature 0 to 1), or
    /// round (None).
    Blades(Option<(u32, f64, f64)>),
    /// Orbit the camera (yaw right, pitch up, degrees) about the point in focus on its axis
    /// (mesh scenes); 0 0 is the scene's own view.
    Orbit([f64; 2]),
    /// Tint the zone of focus (where the paraxial blur is under one pixel).
    ZoneOverlay(bool),
    /// Exposure (EV): the shown image's linear radiance times 2^EV.
    Exposure(f64),
    /// Sensor width (mm), its height following the image's aspect.
    SensorWidth(f64),
    /// Factors on the Seidel model's sums (spherical, coma, astigmatism, Petzval, distortion).
    SeidelScale([f64; 5]),
    Model(ModelKind),
    /// Left half baked, right half traced, identical samples.
    Split(bool),
    /// The split view's |baked - traced| in false colour instead of the two halves.
    ErrorOverlay(bool),
    Chromatic(bool),
    /// Sensor shift (mm).
    Shift([f64; 2]),
    /// Sensor tilt (degrees about x and y).
    Tilt([f64; 2]),
    /// A bundled lens name or a lens file.
    Lens(String),
    /// Reload the lens at this zoom position (1-based) of its zoom file.
    Zoom(usize),
    /// `demo`, a glTF file or an RGB + Z EXR.
    Scene(String),
    /// Render this many frames.
    Frames(u32),
    /// Wait until a table baking in the background is ready.
    WaitBake,
    /// Write the accumulated view as a PNG.
    Screenshot(PathBuf),
    /// Ask for this window size in pixels (a window only; headless runs ignore it).
    WindowSize([u32; 2]),
    /// Minimise or restore the window (a window only; headless runs ignore it).
    Minimise(bool),
    Quit,
}

impl Action {
    /// The script line's first word for this action (`click` for a click in the window, `lens`
    /// for a dropped lens file).
    pub fn verb(&self) -> &'static str {
        match self {
            Action::SppPerFrame(_) => "spp-per-frame",
            Action::Click(_) => "click",
            Action::FNumber(_) => "fnumber",
            Action::Focus(_) => "focus",
            Action::FocusPull { .. } => "focus-pull",
            Action::FocalSurface(_) => "focal-surface",
            Action::FocusPoint(_) => "focus-point",
            Action::Blades(_) => "blades",
            Action::Orbit(_) => "orbit",
            Action::ZoneOverlay(_) => "zone",
            Action::Exposure(_) => "exposure",
            Action::SensorWidth(_) => "sensor",
            Action::SeidelScale(_) => "seidel-scale",
            Action::Model(_) => "model",
            Action::Split(_) => "split",
            Action::ErrorOverlay(_) => "overlay",
            Action::Chromatic(_) => "chromatic",
            Action::Shift(_) => "shift",
            Action::Tilt(_) => "tilt",
            Action::Lens(_) => "lens",
            Action::Zoom(_) => "zoom",
            Action::Scene(_) => "scene",
            Action::Frames(_) => "frames",
            Action::WaitBake => "wait-bake",
            Action::Screenshot(_) => "screenshot",
            Action::WindowSize(_) => "window",
            Action::Minimise(_) => "minimise",
            Action::Quit => "quit",
        }
    }
}

/// Largest exposure change accepted (EV either way): 2^20 takes the darkest linear radiance
/// f32 holds well into the tone curve's shoulder and back.
pub const MAX_EXPOSURE_EV: f64 = 20.0;

/// The words a script understands, for error messages.
const ACTIONS: &str = "spp-per-frame N, click X Y, fnumber F, focus MM, \
     focus-pull FROM_MM TO_MM FRAMES, focal-surface X,Y[,TARGET[,ALPHA]];... [BETA]|off, \
     focus-point X Y [TARGET [ALPHA]], seidel-scale SA COMA AST PETZ DIST, exposure EV, sensor WIDTH_MM, zone on|off, \
     blades COUNT ROTATION_DEG CURVATURE|off, orbit YAW PITCH, \
     model NAME, split on|off, \
     overlay on|off, chromatic on|off, shift X Y, tilt X Y, lens NAME|FILE, zoom POSITION, \
     scene demo|FILE, \
     frames N, wait-bake, screenshot PATH, window W H, minimise on|off, quit";

/// A script line that is not an action.
#[derive(Debug, thiserror::Error)]
#[error("{}:{line}: {message}", file.display())]
pub struct ScriptError {
    pub file: PathBuf,
    pub line: usize,
    pub message: String,
}

/// An action and the script line it came from (1-based).
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptLine {
    pub line: usize,
    pub action: Action,
}

/// Parses a script (`file` names it in errors). Blank lines and `#` comments are skipped.
pub fn parse_script(text: &str, file: &Path) -> Result<Vec<ScriptLine>, ScriptError> {
    let mut lines = Vec::new();
    for (index, raw) in text.lines().enumerate() {
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let action = parse_action(content).map_err(|message| ScriptError {
            file: file.to_path_buf(),
            line: index + 1,
            message,
        })?;
        lines.push(ScriptLine {
            line: index + 1,
            action,
        });
    }
    Ok(lines)
}

/// One action from its words (`click 400 300`).
pub fn parse_action(content: &str) -> Result<Action, String> {
    let words: Vec<&str> = content.split_whitespace().collect();
    let (verb, args) = words
        .split_first()
        .ok_or_else(|| "empty action".to_string())?;
    let expect = |n: usize| -> Result<(), String> {
        if args.len() == n {
            Ok(())
        } else {
            Err(format!(
                "`{verb}` takes {n} argument{}, got {}",
                if n == 1 { "" } else { "s" },
                args.len()
            ))
        }
    };
    let whole = |word: &str, what: &str| -> Result<u32, String> {
        word.parse::<u32>()
            .map_err(|_| format!("`{verb}`: {what} `{word}` is not a whole number"))
    };
    let number = |word: &str, what: &str| -> Result<f64, String> {
        word.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{verb}`: {what} `{word}` is not a finite number"))
    };
    let positive = |word: &str, what: &str| -> Result<f64, String> {
        let value = number(word, what)?;
        if value <= 0.0 {
            return Err(format!(
                "`{verb}`: the {what} must be positive, got {value}"
            ));
        }
        Ok(value)
    };
    let distance = |word: &str| positive(word, "distance (mm)");
    let switch = |word: &str| -> Result<bool, String> {
        match word {
            "on" => Ok(true),
            "off" => Ok(false),
            _ => Err(format!("`{verb}` takes on or off, got `{word}`")),
        }
    };
    Ok(match *verb {
        "spp-per-frame" => {
            expect(1)?;
            let n = whole(args[0], "samples per frame")?;
            if n == 0 {
                return Err("`spp-per-frame` must be at least 1".into());
            }
            Action::SppPerFrame(n)
        }
        "click" => {
            expect(2)?;
            Action::Click([whole(args[0], "x")?, whole(args[1], "y")?])
        }
        "fnumber" => {
            expect(1)?;
            Action::FNumber(positive(args[0], "f-number")?)
        }
        "focus" => {
            expect(1)?;
            Action::Focus(distance(args[0])?)
        }
        "focus-pull" => {
            expect(3)?;
            let frames = whole(args[2], "frame count")?;
            if frames < 2 || frames as u64 > MAX_VIEW_FRAMES {
                return Err(format!(
                    "`focus-pull` takes 2 to {MAX_VIEW_FRAMES} frames, got {frames}"
                ));
            }
            Action::FocusPull {
                from_mm: distance(args[0])?,
                to_mm: distance(args[1])?,
                frames,
            }
        }
        "focal-surface" => match args {
            ["off"] => Action::FocalSurface(None),
            [points] | [points, _] => {
                let beta = match args.get(1) {
                    Some(word) => number(word, "beta")?,
                    None => DEFAULT_BETA,
                };
                let spec =
                    FocalSurfaceSpec::parse(points, beta).map_err(|e| format!("`{verb}`: {e}"))?;
                Action::FocalSurface(Some(spec))
            }
            _ => {
                return Err(format!(
                    "`{verb}` takes X,Y[,TARGET[,ALPHA]];... and an optional BETA, or off"
                ));
            }
        },
        "focus-point" => {
            if !(2..=4).contains(&args.len()) {
                return Err(format!("`{verb}` takes X Y [TARGET [ALPHA]]"));
            }
            let spec = FocalSurfaceSpec::parse(&args.join(","), DEFAULT_BETA)
                .map_err(|e| format!("`{verb}`: {e}"))?;
            Action::FocusPoint(spec.points[0])
        }
        "blades" => match args {
            ["off"] => Action::Blades(None),
            [count, rotation, curvature] => {
                let count = whole(count, "blade count")?;
                let rotation = number(rotation, "rotation (degrees)")?;
                let curvature = number(curvature, "curvature")?;
                if count < 3 || !(0.0..=1.0).contains(&curvature) {
                    return Err(format!(
                        "`blades` takes at least 3 blades and a curvature from 0 to 1, got \
                         {count} and {curvature}"
                    ));
                }
                Action::Blades(Some((count, rotation, curvature)))
            }
            _ => {
                return Err(format!(
                    "`{verb}` takes COUNT ROTATION_DEG CURVATURE, or off"
                ));
            }
        },
        "orbit" => {
            expect(2)?;
            let angles = [number(args[0], "yaw")?, number(args[1], "pitch")?];
            if angles.iter().any(|a| a.abs() > 180.0) {
                return Err(format!(
                    "`orbit` takes angles within +-180 degrees, got {angles:?}"
                ));
            }
            Action::Orbit(angles)
        }
        "zone" => {
            expect(1)?;
            Action::ZoneOverlay(switch(args[0])?)
        }
        "exposure" => {
            expect(1)?;
            let ev = number(args[0], "exposure (EV)")?;
            if ev.abs() > MAX_EXPOSURE_EV {
                return Err(format!(
                    "`exposure` takes -{MAX_EXPOSURE_EV} to {MAX_EXPOSURE_EV} EV, got {ev}"
                ));
            }
            Action::Exposure(ev)
        }
        "sensor" => {
            expect(1)?;
            Action::SensorWidth(positive(args[0], "sensor width (mm)")?)
        }
        "seidel-scale" => {
            expect(5)?;
            let mut factors = [0.0; 5];
            for (factor, (word, name)) in factors
                .iter_mut()
                .zip(args.iter().zip(AberrationScale::NAMES))
            {
                *factor = number(word, name)?;
            }
            AberrationScale::from_array(factors).map_err(|e| format!("`{verb}`: {e}"))?;
            Action::SeidelScale(factors)
        }
        "model" => {
            expect(1)?;
            Action::Model(args[0].parse().map_err(|e| format!("{e}"))?)
        }
        "split" => {
            expect(1)?;
            Action::Split(switch(args[0])?)
        }
        "overlay" => {
            expect(1)?;
            Action::ErrorOverlay(switch(args[0])?)
        }
        "chromatic" => {
            expect(1)?;
            Action::Chromatic(switch(args[0])?)
        }
        "shift" => {
            expect(2)?;
            Action::Shift([number(args[0], "x")?, number(args[1], "y")?])
        }
        "tilt" => {
            expect(2)?;
            Action::Tilt([number(args[0], "x")?, number(args[1], "y")?])
        }
        "lens" => {
            expect(1)?;
            Action::Lens(args[0].to_string())
        }
        "zoom" => {
            expect(1)?;
            let position = whole(args[0], "zoom position")?;
            if position == 0 {
                return Err("`zoom` positions count from 1".into());
            }
            Action::Zoom(position as usize)
        }
        "scene" => {
            expect(1)?;
            Action::Scene(args[0].to_string())
        }
        "frames" => {
            expect(1)?;
            let n = whole(args[0], "frame count")?;
            if n as u64 > MAX_VIEW_FRAMES {
                return Err(format!("`frames` takes at most {MAX_VIEW_FRAMES}, got {n}"));
            }
            Action::Frames(n)
        }
        "wait-bake" => {
            expect(0)?;
            Action::WaitBake
        }
        "screenshot" => {
            expect(1)?;
            let path = PathBuf::from(args[0]);
            // Screenshots are PNG; any other name would hold PNG bytes under a wrong extension.
            if !path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("png"))
            {
                return Err(format!(
                    "`screenshot`: {} must end in .png (screenshots are PNG)",
                    path.display()
                ));
            }
            Action::Screenshot(path)
        }
        "window" => {
            expect(2)?;
            let size = [whole(args[0], "width")?, whole(args[1], "height")?];
            if size.contains(&0)
                || size
                    .iter()
                    .any(|&side| u64::from(side) > crate::limits::MAX_IMAGE_SIDE)
            {
                return Err(format!(
                    "`window`: each side must be 1 to {} pixels",
                    crate::limits::MAX_IMAGE_SIDE
                ));
            }
            Action::WindowSize(size)
        }
        "minimise" => {
            expect(1)?;
            Action::Minimise(switch(args[0])?)
        }
        "quit" => {
            expect(0)?;
            Action::Quit
        }
        other => {
            return Err(format!(
                "unknown action `{other}` (expected one of: {ACTIONS})"
            ));
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_action_parses_and_errors_name_the_line() {
        let text = "# demo\nspp-per-frame 4\nclick 400 300\nfnumber 2.8\nmodel baked\n\
                    split on\noverlay off\nchromatic on\nshift 1 -2\ntilt 0 3.5\nlens cooke-triplet\n\
                    scene demo\nframes 10 # ten\nwait-bake\nscreenshot out/a.png\nquit\n";
        let lines = parse_script(text, Path::new("s.txt")).unwrap();
        assert_eq!(lines.len(), 15);
        assert_eq!(lines[0].line, 2);
        assert_eq!(lines[1].action, Action::Click([400, 300]));
        assert_eq!(lines[3].action, Action::Model(ModelKind::Baked));
        assert_eq!(lines[7].action, Action::Shift([1.0, -2.0]));
        assert_eq!(lines[11].action, Action::Frames(10));
        assert_eq!(lines[14].action, Action::Quit);
        // Each action names the script word that gives it, as the window's key map checks.
        for line in text.lines().filter_map(|l| l.split('#').next()) {
            if let Some(verb) = line.split_whitespace().next() {
                assert_eq!(parse_action(line).unwrap().verb(), verb, "{line}");
            }
        }
        assert_eq!(parse_action("zoom 2").unwrap(), Action::Zoom(2));
        let pull = parse_action("focus-pull 1000 6000 16").unwrap();
        assert_eq!(
            pull,
            Action::FocusPull {
                from_mm: 1000.0,
                to_mm: 6000.0,
                frames: 16
            }
        );
        assert_eq!(parse_action("focus 2500").unwrap(), Action::Focus(2500.0));
        for (bad, needle) in [
            ("frames ten", "not a whole number"),
            ("click 1", "takes 2 arguments"),
            ("model pinhole", "unknown lens model"),
            ("split maybe", "on or off"),
            ("fnumber -2", "positive"),
            ("fnumber nan", "finite"),
            ("focus 0", "must be positive"),
            ("focus-pull 1000 6000 1", "2 to"),
            ("focus-pull 1000 x 16", "not a finite number"),
            ("spp-per-frame 0", "at least 1"),
            ("frames 10000001", "at most 10000000"),
            ("zoom 0", "count from 1"),
            ("zoom", "takes 1 argument"),
            ("screenshot shot.jpg", "must end in .png"),
            ("screenshot shot", "must end in .png"),
        ] {
            let text = format!("frames 1\n\n{bad}\nquit\n");
            let error = parse_script(&text, Path::new("dir/s.txt")).unwrap_err();
            assert_eq!(error.line, 3, "{bad}");
            let message = error.to_string();
            assert!(message.starts_with("dir/s.txt:3: "), "{message}");
            assert!(message.contains(needle), "{bad}: {message}");
        }
    }
}
