//! The link to one worker process, as the supervisor keeps it: its ports, its process and
//! generation, where it stands ([`LinkState`], the link's state machine: no other file sets a
//! state but through the methods here and the intake and failure handling that drive it), and
//! what the supervisor remembers of it between commands.

use std::path::PathBuf;
use std::process::Child;
use std::time::Instant;

use rogue_gym_ipc::{BlockSample, SupervisorPorts};

use crate::wire::answer::ANSWER_WORDS;

/// Where a worker's link stands: the state machine of one worker as the supervisor sees it.
pub(super) enum LinkState {
    /// Dead, waiting out its restart backoff; respawned at `until` (restart policy).
    Down { until: Instant, then_reset: bool },
    /// Process started, waiting for its READY answer.
    Starting { since: Instant, then_reset: bool },
    /// Nothing outstanding.
    Idle,
    /// A command is outstanding.
    Pending { since: Instant },
    /// Its answer has arrived and waits to be taken.
    Ready(Arrived),
}

/// An answer to a reset or step as it arrived: its words ([`crate::wire::answer::Answer`],
/// decoded when it is taken), its command's sequence number, and when the worker published it
/// (`CLOCK_MONOTONIC`, ns). The sample itself is let go at once.
#[derive(Clone, Copy, Debug)]
pub(super) struct Arrived {
    pub(super) words: [u64; ANSWER_WORDS],
    pub(super) seq: u64,
    pub(super) ready_ns: u64,
}

impl Arrived {
    /// The answer `sample` carries (zeros where it is too short to hold the words:
    /// [`crate::wire::answer::Answer::decode`] refuses those).
    pub(super) fn of(sample: &BlockSample) -> Self {
        let mut words = [0u64; ANSWER_WORDS];
        if let Some(w) = sample.payload().get(..ANSWER_WORDS) {
            words.copy_from_slice(w);
        }
        let h = sample.user_header();
        Arrived {
            words,
            seq: h.seq,
            ready_ns: h.ready_ns,
        }
    }
}

impl LinkState {
    /// Lost and not back yet: waiting out its backoff, or starting.
    pub(super) fn coming_back(&self) -> bool {
        matches!(self, LinkState::Down { .. } | LinkState::Starting { .. })
    }
    /// Nothing outstanding.
    pub(super) fn is_idle(&self) -> bool {
        matches!(self, LinkState::Idle)
    }
    /// A command is outstanding.
    pub(super) fn is_pending(&self) -> bool {
        matches!(self, LinkState::Pending { .. })
    }
    /// What a call that reached its bound still waits for, if anything.
    pub(super) fn waiting_for(&self) -> Option<&'static str> {
        Some(match self {
            LinkState::Down { .. } => "waiting out its restart backoff",
            LinkState::Starting { .. } => "starting",
            LinkState::Pending { .. } => "not answering",
            _ => return None,
        })
    }
}

/// Where a reset or step command's envs write their rows.
#[derive(Clone, Copy)]
pub(super) enum Target<'a> {
    /// Every env of the block into slot `s`.
    Slot(usize),
    /// Each env of the block into its own slot (`s + 1`; 0: left alone).
    Each(&'a [u64]),
}

impl<'a> Target<'a> {
    /// The command's `target` word and, where the envs' slots differ (or some are left
    /// alone), the per-env words of a [`crate::wire::Command::subset`] command.
    pub(super) fn words(self) -> (u32, Option<&'a [u64]>) {
        match self {
            Target::Slot(s) => (s as u32 + 1, None),
            Target::Each(t) => match t.first() {
                Some(&first) if first != 0 && t.iter().all(|&w| w == first) => (first as u32, None),
                _ => (0, Some(t)),
            },
        }
    }
}

pub(super) struct WorkerLink {
    pub(super) ports: SupervisorPorts,
    pub(super) child: Option<Child>,
    pub(super) pid: u32,
    pub(super) generation: u64,
    pub(super) seq: u64,
    pub(super) state: LinkState,
    pub(super) restarted: bool,
    /// It died while idle and was replaced (restart policy): its envs' episodes were cut, so
    /// its next command resets them (and they report `restarted`).
    pub(super) cut: bool,
    pub(super) stderr_path: PathBuf,
    /// Failures of this worker in a row, with no answer to a command in between (see
    /// [`restart_backoff`]); an answer ends the streak.
    pub(super) restart_streak: u32,
    /// The command whose answer it gave last: the copy of the episode books to read
    /// ([`crate::wire::books`]).
    pub(super) delivered: Option<u64>,
    /// Its envs start from episode 0 at the next reset (a new pool, or a new seed schedule).
    pub(super) first_episodes: bool,
    /// Action extras staged for its next step ([`crate::Pool::stage_action_extras`]), encoded
    /// as a call file.
    pub(super) action_extras: Option<Vec<u8>>,
    /// Env steps served since this incarnation started (for `recycle_after_steps`).
    pub(super) served: u64,
    /// Commands sent through its ports before its current process started (those it read
    /// are counted from then: `StatsBuffer::read`).
    pub(super) sent_before: u64,
    /// Its successor while it builds its envs (see `recycling`).
    pub(super) successor: Option<super::recycling::Successor>,
    /// It was replaced by plan: the envs of its next block report `worker_recycled`.
    pub(super) recycled: bool,
    /// When its resident memory was last read, and what it was (bytes).
    pub(super) rss_read: Option<Instant>,
    pub(super) rss: u64,
    /// How much it grew between the last two readings.
    pub(super) rss_growth: u64,
    /// No successor is started before this (one failed).
    pub(super) recycle_pause: Option<Instant>,
    /// Its envs run on threads, and some are in flight under partial commands
    /// ([`crate::wire::Command::partial`]): it answers them one by one, and takes more commands meanwhile.
    pub(super) partial: bool,
}

impl WorkerLink {
    /// A command was sent just now: it is outstanding.
    pub(super) fn pending_now(&mut self) {
        self.state = LinkState::Pending {
            since: Instant::now(),
        };
    }
    /// Nothing outstanding any more.
    pub(super) fn idle(&mut self) {
        self.state = LinkState::Idle;
    }
    /// Its process (`then_reset`: one replacing a lost worker, whose envs reset once it is
    /// ready) was started just now.
    pub(super) fn starting_now(&mut self, then_reset: bool) {
        self.state = LinkState::Starting {
            since: Instant::now(),
            then_reset,
        };
    }
    /// Forget an answer that arrived and was not taken (a reset drains it).
    pub(super) fn forget_answer(&mut self) {
        if matches!(self.state, LinkState::Ready(_)) {
            self.state = LinkState::Idle;
        }
    }

    /// The link to a worker not started yet, over its `ports`.
    pub(super) fn new(ports: SupervisorPorts) -> Self {
        WorkerLink {
            ports,
            child: None,
            pid: 0,
            generation: 0,
            seq: 0,
            state: LinkState::Idle,
            restarted: false,
            served: 0,
            sent_before: 0,
            successor: None,
            recycled: false,
            rss_read: None,
            rss: 0,
            rss_growth: 0,
            recycle_pause: None,
            partial: false,
            cut: false,
            restart_streak: 0,
            delivered: None,
            first_episodes: true,
            stderr_path: PathBuf::new(),
            action_extras: None,
        }
    }
}
