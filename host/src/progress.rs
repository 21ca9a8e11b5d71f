//! Progress on stderr for stages that can run past a second (reading, k-means, fitting,
//! evaluation, rendering).
//!
//! A stage draws nothing for its first second, so quick runs stay silent, and nothing at all
//! unless stderr is a terminal, so logs and pipes never receive control sequences.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::mpsc;
use std::time::Duration;

/// How long a stage runs silently before its bar appears.
pub const DELAY: Duration = Duration::from_secs(1);

/// One running stage; its bar is cleared when the stage is dropped.
pub struct Stage {
    bar: ProgressBar,
    done: Option<mpsc::Sender<()>>,
    reveal: Option<std::thread::JoinHandle<()>>,
}

impl Stage {
    /// A stage of unknown length (a spinner with the elapsed time).
    pub fn spinner(name: &str) -> Self {
        Self::start(name, None, stderr_target)
    }

    /// A stage of `total` steps (a bar with a count and an estimate of the time left).
    pub fn counted(name: &str, total: u64) -> Self {
        Self::start(name, Some(total), stderr_target)
    }

    /// `target` is called after [`DELAY`] if the stage is still running; `None` keeps it hidden.
    pub fn start(
        name: &str,
        total: Option<u64>,
        target: fn() -> Option<ProgressDrawTarget>,
    ) -> Self {
        let bar = ProgressBar::with_draw_target(total, ProgressDrawTarget::hidden());
        let template = match total {
            Some(_) => "{spinner} {msg} [{bar:30}] {pos}/{len} ({elapsed}, eta {eta})",
            None => "{spinner} {msg} ({elapsed})",
        };
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_message(name.to_owned());
        let (done, wait) = mpsc::channel::<()>();
        let shown = bar.clone();
        // No thread to spare (a memory or process limit) only means no progress bar.
        let reveal = std::thread::Builder::new()
            .spawn(move || {
                if wait.recv_timeout(DELAY) == Err(mpsc::RecvTimeoutError::Timeout)
                    && let Some(t) = target()
                {
                    shown.set_draw_target(t);
                    shown.enable_steady_tick(Duration::from_millis(120));
                }
            })
            .ok();
        Stage {
            bar,
            done: Some(done),
            reveal,
        }
    }

    /// Counts `n` more steps done.
    pub fn inc(&self, n: u64) {
        self.bar.inc(n);
    }

    /// A handle to count steps from worker threads.
    pub fn bar(&self) -> &ProgressBar {
        &self.bar
    }
}

impl Drop for Stage {
    fn drop(&mut self) {
        drop(self.done.take());
        if let Some(h) = self.reveal.take() {
            let _ = h.join();
        }
        self.bar.finish_and_clear();
    }
}

fn stderr_target() -> Option<ProgressDrawTarget> {
    std::io::stderr()
        .is_terminal()
        .then(ProgressDrawTarget::stderr)
}

/// Runs `work` as a spinner stage.
pub fn stage<T>(name: &str, work: impl FnOnce() -> T) -> T {
    let _stage = Stage::spinner(name);
    work()
}

#[cfg(test)]
mod tests {
    use super::*;
    use indicatif::TermLike;
    use std::sync::{Arc, Mutex};

    /// A terminal that records what is written to it.
    #[derive(Debug, Clone, Default)]
    struct Screen(Arc<Mutex<String>>);

    impl TermLike for Screen {
        fn width(&self) -> u16 {
            100
        }
        fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
            Ok(())
        }
        fn write_line(&self, s: &str) -> std::io::Result<()> {
            self.write_str(s)
        }
        fn write_str(&self, s: &str) -> std::io::Result<()> {
            self.0
                .lock()
                .map(|mut t| t.push_str(s))
                .map_err(|_| std::io::ErrorKind::Other.into())
        }
        fn clear_line(&self) -> std::io::Result<()> {
            Ok(())
        }
        fn flush(&self) -> std::io::Result<()> {
            Ok(())
        }
    }

    static SCREEN: Mutex<Option<Screen>> = Mutex::new(None);

    fn screen_target() -> Option<ProgressDrawTarget> {
        let s = SCREEN.lock().ok()?.clone()?;
        Some(ProgressDrawTarget::term_like(Box::new(s)))
    }

    #[test]
    fn quick_stages_draw_nothing_and_long_ones_draw_their_name() {
        let screen = Screen::default();
        *SCREEN.lock().unwrap() = Some(screen.clone());
        {
            let s = Stage::start("quick", Some(10), screen_target);
            s.inc(10);
        }
        assert_eq!(screen.0.lock().unwrap().as_str(), "");
        {
            let s = Stage::start("fitting", Some(4), screen_target);
            s.inc(1);
            std::thread::sleep(DELAY + Duration::from_millis(400));
        }
        let shown = screen.0.lock().unwrap().clone();
        assert!(
            shown.contains("fitting") && shown.contains("1/4"),
            "{shown:?}"
        );
    }
}
