//! Scripted input for the viewer: the same states and the same render
//! thread as the window, without a display, timed event by event.
//!
//! The format, one command a line (`#` starts a comment):
//!
//! ```text
//! drag DX DY      drag the picture by DX, DY window pixels (x right, y down)
//! wheel N [X Y]   N wheel notches (positive: zoom in) about window point
//!                 X Y (default: the centre), as N single notches: past a
//!                 zoom limit the view stops there
//! key K           a key as the window takes it: Left Right Up Down , . m t
//!                 s v [ ] r Home q Escape (space plays only in a window:
//!                 use play; the help and fullscreen are a window's)
//! resize W H      the window resized to W x H pixels
//! play N          the timeline's next N frames, each once the last is shown
//! wait            until the frame loop's picture shows every command so far
//! wait-converged  until that picture is refined to the top of the ladder
//!                 (--refine-spp) and the render thread is idle
//! sleep MS        nothing for MS milliseconds (the thread refines meanwhile)
//! save PATH       the picture of every command so far as PNG (or TGA): the
//!                 frame loop's, or right after wait-converged the converged
//!                 one; with the overlay on (key t), the frame loop's picture
//!                 painted black where it traced
//! ```
//!
//! Commands are sent as fast as a hand could send them: a picture may
//! answer several (the render thread renders the latest state), and each
//! command is timed to the first picture that shows it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec2;

use super::state::{Effect, Input, Key, ViewState, Viewer};
use super::worker::{Finished, RenderThread, REFINE_MODE};
use crate::clock;
use crate::frame_loop::FrameStats;
use crate::output::{csv_text, CsvError, Floats};

/// One command of a script.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    Input(Input),
    Play(u32),
    Wait,
    WaitConverged,
    Sleep(u32),
    Save(PathBuf),
}

/// A command and the line it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptLine {
    pub number: usize,
    pub text: String,
    pub command: Command,
}

/// A script line that cannot be run, and why.
#[derive(Debug, thiserror::Error)]
#[error("{}:{line}: {message}", path.display())]
pub struct ScriptError {
    pub path: PathBuf,
    pub line: usize,
    pub message: String,
}

/// The commands of script `text` (read from `path`, which errors name);
/// `size` is the picture's, the default point of a wheel.
pub fn parse_script(
    text: &str,
    path: &Path,
    size: (u32, u32),
) -> Result<Vec<ScriptLine>, ScriptError> {
    let mut lines = Vec::new();
    // A wheel without X Y turns about the centre of the window as resized.
    let mut size = size;
    for (index, raw) in text.lines().enumerate() {
        let number = index + 1;
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let error = |message: String| ScriptError {
            path: path.to_path_buf(),
            line: number,
            message,
        };
        let command = parse_command(content, size).map_err(error)?;
        if let Command::Input(Input::Resize(width, height)) = command {
            size = (width, height);
        }
        lines.push(ScriptLine {
            number,
            text: content.to_string(),
            command,
        });
    }
    Ok(lines)
}

fn parse_command(content: &str, size: (u32, u32)) -> Result<Command, String> {
    let words: Vec<&str> = content.split_whitespace().collect();
    let number = |name: &str, word: &str| -> Result<f64, String> {
        word.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{}: {name} '{word}' is not a number", words[0]))
    };
    let centre = DVec2::new(f64::from(size.0), f64::from(size.1)) * 0.5;
    match words[..] {
        ["drag", dx, dy] => Ok(Command::Input(Input::Drag(DVec2::new(
            number("DX", dx)?,
            number("DY", dy)?,
        )))),
        ["drag", ..] => Err("drag takes DX DY (window pixels)".to_string()),
        ["wheel", n, ref at @ ..] if at.is_empty() || at.len() == 2 => {
            let notches = n
                .parse::<i32>()
                .map_err(|_| format!("wheel: N '{n}' is not a whole number of notches"))?;
            let at = match at {
                [x, y] => DVec2::new(number("X", x)?, number("Y", y)?),
                _ => centre,
            };
            Ok(Command::Input(Input::Wheel { notches, at }))
        }
        ["wheel", ..] => Err("wheel takes N [X Y]".to_string()),
        ["key", "space" | "Space"] => Err(
            "key space plays the timeline in real time, in a window; a script plays with \
             `play N`"
                .to_string(),
        ),
        ["key", name] => match Key::parse(name) {
            Some(Key::Help | Key::Fullscreen) => Err(format!(
                "key {name} shows the help or goes fullscreen, in a window; a script has \
                 none (resize W H sets its size)"
            )),
            Some(key) => Ok(Command::Input(Input::Key(key))),
            None => Err(format!(
                "key: unknown key '{name}' (Left Right Up Down , . m t s v [ ] r Home q Escape)"
            )),
        },
        ["key", ..] => Err("key takes one key".to_string()),
        ["resize", w, h] => {
            let side = |name: &str, word: &str| {
                word.parse::<u32>()
                    .ok()
                    .filter(|&v| v > 0)
                    .ok_or_else(|| format!("resize: {name} '{word}' is not a number of pixels"))
            };
            Ok(Command::Input(Input::Resize(side("W", w)?, side("H", h)?)))
        }
        ["resize", ..] => Err("resize takes W H (pixels)".to_string()),
        ["play", n] => n
            .parse::<u32>()
            .map(Command::Play)
            .map_err(|_| format!("play: N '{n}' is not a number of frames")),
        ["play", ..] => Err("play takes N (frames)".to_string()),
        ["wait"] => Ok(Command::Wait),
        ["wait", ..] => Err("wait takes nothing".to_string()),
        ["wait-converged"] => Ok(Command::WaitConverged),
        ["wait-converged", ..] => Err("wait-converged takes nothing".to_string()),
        ["sleep", ms] => ms
            .parse::<u32>()
            .map(Command::Sleep)
            .map_err(|_| format!("sleep: MS '{ms}' is not a whole number of milliseconds")),
        ["sleep", ..] => Err("sleep takes MS (milliseconds)".to_string()),
        ["save", path] => Ok(Command::Save(PathBuf::from(path))),
        ["save", ..] => Err("save takes one PATH (no spaces)".to_string()),
        [other, ..] => Err(format!(
            "unknown command '{other}' (drag, wheel, key, resize, play, wait, \
             wait-converged, sleep, save)"
        )),
        [] => unreachable!("blank lines are skipped"),
    }
}

/// What one command cost: the first picture that showed it.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct EventStats {
    pub line: usize,
    pub event: String,
    /// The state it led to (None: it changed nothing shown).
    pub frame: u32,
    pub reuse: bool,
    /// How the frame loop made the picture.
    pub mode: Option<&'static str>,
    /// From the command to its complete picture, ms.
    pub ms_to_picture: Option<f64>,
    /// From the command to the first picture showing it (coarse or
    /// complete), ms.
    pub ms_to_first_picture: Option<f64>,
    /// From the command to the converged picture showing it (refined to
    /// the top of the ladder), ms; None if none came before the end.
    pub ms_to_converged: Option<f64>,
    /// Pixels of the picture shown.
    pub pixels: u64,
    /// What the complete picture that answered it cost, as the frame loop
    /// recorded it (its columns `picture.frame`, `picture.total_ms`, ...).
    pub picture: Option<FrameStats>,
}

/// What the script asks to be written: (path, picture).
pub type Saved = (PathBuf, image::RgbImage);

/// Runs `lines` through `thread` from the opening view; `save` writes a
/// picture (a `save` command's, or `key s`'s to `next_save()`). Returns
/// one row per command that asks for a picture (the opening view first);
/// if `thread` is interrupted, those of the commands run until then.
pub fn run_script(
    thread: &RenderThread,
    viewer: &Viewer,
    lines: &[ScriptLine],
    next_save: &mut dyn FnMut() -> PathBuf,
    save: &mut dyn FnMut(&Path, &image::RgbImage) -> Result<(), String>,
) -> Result<Vec<EventStats>, String> {
    let mut state = viewer.opening();
    let mut overlay = false;
    // Whether the last command was wait-converged: a save then writes
    // the converged picture.
    let mut converged = false;
    let mut generation = 1;
    // (line, text, generation, state, sent)
    let mut sent: Vec<(usize, String, u64, ViewState, Instant)> = Vec::new();
    sent.push((
        0,
        "open".to_string(),
        generation,
        state.clone(),
        Instant::now(),
    ));
    thread.request(generation, state.clone());
    let mut ask = |state: &ViewState, line: &ScriptLine, text: String, generation: &mut u64| {
        *generation += 1;
        sent.push((
            line.number,
            text,
            *generation,
            state.clone(),
            Instant::now(),
        ));
        thread.request(*generation, state.clone());
    };
    let picture = |generation: u64, converged: bool| {
        if converged {
            thread.wait_converged(generation)
        } else {
            thread.wait_for(generation)
        }
    };
    // Run as a closure so that an interrupt, which gives up the wait
    // under way, ends the commands but not the rows of those that ran.
    let ran = (|| -> Result<(), String> {
        for line in lines {
            if thread.interrupted() {
                break;
            }
            let was_converged = std::mem::take(&mut converged);
            match &line.command {
                Command::Input(input) => match viewer.apply(&mut state, *input) {
                    Effect::Changed => ask(&state, line, line.text.clone(), &mut generation),
                    Effect::Nothing
                    | Effect::TogglePlay
                    | Effect::ToggleHelp
                    | Effect::ToggleFullscreen => converged = was_converged,
                    Effect::ToggleOverlay => {
                        overlay = !overlay;
                        converged = was_converged;
                    }
                    Effect::Save => {
                        let picture = picture(generation, was_converged)?;
                        save(&next_save(), picture.shown(overlay))?;
                        converged = was_converged;
                    }
                    Effect::Quit => break,
                },
                Command::Play(frames) => {
                    for _ in 0..*frames {
                        if viewer.advance(&mut state) != Effect::Changed {
                            break;
                        }
                        let text = format!("play frame {}", state.frame);
                        ask(&state, line, text, &mut generation);
                        thread.wait_for(generation)?;
                    }
                }
                Command::Wait => {
                    thread.wait_for(generation)?;
                }
                Command::WaitConverged => {
                    thread.wait_converged(generation)?;
                    converged = true;
                }
                Command::Sleep(ms) => {
                    std::thread::sleep(std::time::Duration::from_millis(u64::from(*ms)));
                    converged = was_converged;
                }
                Command::Save(path) => {
                    let picture = picture(generation, was_converged)?;
                    save(path, picture.shown(overlay))?;
                    converged = was_converged;
                }
            }
        }
        thread.wait_for(generation)?;
        Ok(())
    })();
    match ran {
        Err(_) if thread.interrupted() => {}
        other => other?,
    }
    let log = thread.log();
    Ok(sent
        .into_iter()
        .map(|(line, event, generation, state, at)| {
            let first = log.iter().find(|f| f.generation >= generation);
            let answer = log
                .iter()
                .find(|f| f.generation >= generation && f.complete && f.mode != REFINE_MODE);
            let converged = log
                .iter()
                .find(|f| f.generation >= generation && f.converged);
            let since = |f: &Finished| clock::ms(f.done.duration_since(at));
            let (width, height) = viewer.size_of(&state);
            EventStats {
                line,
                event,
                frame: state.frame,
                reuse: state.reuse,
                mode: answer.map(|f| f.mode),
                ms_to_first_picture: first.map(since),
                ms_to_picture: answer.map(since),
                ms_to_converged: converged.map(since),
                pixels: u64::from(width) * u64::from(height),
                picture: answer.map(|f| f.stats.clone()),
            }
        })
        .collect())
}

/// The statistics as CSV, one row per command, times to the
/// microsecond.
pub fn stats_csv(rows: &[EventStats]) -> Result<String, CsvError> {
    let columns_of = EventStats {
        mode: Some(""),
        ms_to_picture: Some(0.0),
        ms_to_first_picture: Some(0.0),
        ms_to_converged: Some(0.0),
        picture: Some(FrameStats::every_column()),
        ..EventStats::default()
    };
    csv_text(rows, &columns_of, Floats::Fixed(3))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_command_and_names_the_line_of_a_bad_one() {
        let text = "# a pan\ndrag -23.04 0\nwheel 2 100 50 # in\nwheel -1\nkey m\nkey Left\n\
                    play 3\nwait\nwait-converged\nsleep 20\nsave out/a.png\n";
        let lines = parse_script(text, Path::new("s.txt"), (640, 480)).unwrap();
        let commands: Vec<&Command> = lines.iter().map(|l| &l.command).collect();
        assert_eq!(
            commands,
            [
                &Command::Input(Input::Drag(DVec2::new(-23.04, 0.0))),
                &Command::Input(Input::Wheel {
                    notches: 2,
                    at: DVec2::new(100.0, 50.0)
                }),
                &Command::Input(Input::Wheel {
                    notches: -1,
                    at: DVec2::new(320.0, 240.0)
                }),
                &Command::Input(Input::Key(Key::M)),
                &Command::Input(Input::Key(Key::Left)),
                &Command::Play(3),
                &Command::Wait,
                &Command::WaitConverged,
                &Command::Sleep(20),
                &Command::Save(PathBuf::from("out/a.png")),
            ]
        );
        assert_eq!(lines[0].number, 2);
        for (bad, says) in [
            ("drag 1", "drag takes DX DY"),
            ("drag x 1", "DX 'x' is not a number"),
            ("wheel 1.5", "not a whole number"),
            ("wheel 1 2", "wheel takes N [X Y]"),
            ("key space", "play N"),
            ("key F5", "unknown key 'F5'"),
            ("key h", "in a window"),
            ("key F11", "in a window"),
            ("zoom 2", "unknown command 'zoom'"),
            ("drag inf 0", "not a number"),
            ("resize 0 10", "W '0' is not a number of pixels"),
            ("resize 10", "resize takes W H"),
            ("wait-converged 2", "wait-converged takes nothing"),
            ("sleep -1", "MS '-1' is not a whole number"),
        ] {
            let err = parse_script(&format!("wait\n{bad}\n"), Path::new("s.txt"), (640, 480))
                .unwrap_err();
            assert_eq!(err.line, 2, "{bad}");
            let text = err.to_string();
            assert!(text.starts_with("s.txt:2: "), "{text}");
            assert!(text.contains(says), "{bad}: {text}");
        }
    }
}
