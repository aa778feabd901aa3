//! Per-row work that every forward pass over one data set does alike: each row's reference
//! and the albedo view from it, and the initial scale factors of the whole set.
//!
//! The ensemble's members ([`crate::ensemble`]) step through the rows their base has just
//! stepped through, with the same references and albedo model. With one [`SharedRows`]
//! among them, each row's reference and albedo view are computed once and read by every
//! pass; the albedo view is most of a Sun-only pass's time, and a reference computed per
//! row (a long set, [`References::Computed`]) is an ephemeris evaluation. Results are
//! bit-identical to computing them in every pass: the same function of the same inputs.
//!
//! Few rows are kept: the members ask for the row the base has just computed, and larger
//! stores (enough for the Sun-line probe's window, say) measured slower, the pass without
//! members too (docs/performance.md). A row not kept is computed again, never wrong.
//!
//! The passes that share one must read the same inputs ([`crate::prepare::RunInputs`]) and
//! the same prepared telemetry; [`crate::forward::ForwardPass`] hands its own to the
//! members it starts and to no one else.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use pdcal_albedo::{AlbedoModel, AlbedoView};
use pdcal_ephem::Reference;

use crate::init::InitialScales;
use crate::references::albedo_into;
use crate::{FilterError, References};

/// Rows kept ([module docs](self)).
const KEPT_ROWS: usize = 8;

/// Views of dropped rows kept for their buffers, at most.
const SPARE_VIEWS: usize = 4;

/// The kept rows, oldest first, and the buffers of dropped rows' views: a view's buffers
/// are large and only grow, so a new view is computed into a dropped one's.
#[derive(Default)]
struct Kept {
    rows: VecDeque<(usize, Row)>,
    spare: Vec<AlbedoView>,
}

impl Kept {
    /// Row `index`, kept as the newest if it was not kept, the oldest dropped beyond
    /// [`KEPT_ROWS`]; `reference` computes its reference.
    fn row(
        &mut self,
        index: usize,
        reference: impl FnOnce() -> Result<Reference, FilterError>,
    ) -> Result<&mut Row, FilterError> {
        let at = match self.rows.iter().rposition(|(k, _)| *k == index) {
            Some(at) => at,
            None => {
                let row = Row {
                    reference: reference()?,
                    view: None,
                };
                if self.rows.len() >= KEPT_ROWS {
                    self.drop_oldest();
                }
                self.rows.push_back((index, row));
                self.rows.len() - 1
            }
        };
        Ok(&mut self.rows[at].1)
    }

    fn drop_oldest(&mut self) {
        let view = self.rows.pop_front().and_then(|(_, row)| row.view);
        if let Some(view) = view.and_then(|v| Arc::try_unwrap(v).ok())
            && self.spare.len() < SPARE_VIEWS
        {
            self.spare.push(view);
        }
    }
}

/// One row's shared results.
struct Row {
    reference: Reference,
    /// The albedo view from `reference`, once a pass asked for it.
    view: Option<Arc<AlbedoView>>,
}

/// The per-row results of the passes over one data set ([module docs](self)).
pub struct SharedRows {
    kept: Mutex<Kept>,
    initial: OnceLock<InitialScales>,
}

impl SharedRows {
    /// An empty store, for the passes about to read one data set.
    pub fn new() -> Arc<SharedRows> {
        Arc::new(SharedRows {
            kept: Mutex::new(Kept::default()),
            initial: OnceLock::new(),
        })
    }

    /// Row `index`'s reference from `references`, computed only if not kept.
    pub fn reference(
        &self,
        references: &References<'_>,
        index: usize,
    ) -> Result<Reference, FilterError> {
        let mut kept = self.lock();
        Ok(kept.row(index, || references.at(index))?.reference)
    }

    /// The albedo view of `model` from row `index`'s reference `reference`, computed only
    /// if not kept.
    pub fn albedo(
        &self,
        reference: &Reference,
        model: &AlbedoModel,
        index: usize,
    ) -> Result<Arc<AlbedoView>, FilterError> {
        let mut kept = self.lock();
        if let Some(view) = &kept.row(index, || Ok(*reference))?.view {
            return Ok(Arc::clone(view));
        }
        let mut view = kept.spare.pop().unwrap_or_default();
        albedo_into(reference, model, &mut view, index)?;
        let view = Arc::new(view);
        kept.row(index, || Ok(*reference))?.view = Some(Arc::clone(&view));
        Ok(view)
    }

    /// The initial scale factors, from `compute` the first time they are asked for.
    pub fn initial_scales(
        &self,
        compute: impl FnOnce() -> Result<InitialScales, FilterError>,
    ) -> Result<InitialScales, FilterError> {
        if let Some(initial) = self.initial.get() {
            return Ok(initial.clone());
        }
        let initial = compute()?;
        Ok(self.initial.get_or_init(|| initial).clone())
    }

    fn lock(&self) -> MutexGuard<'_, Kept> {
        // A pass that panicked mid-row left no half-made row behind: rows are pushed whole.
        self.kept.lock().unwrap_or_else(|e| e.into_inner())
    }
}
