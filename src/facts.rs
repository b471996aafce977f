//! What a stage says about its run, typed by the stage: each stage's result implements
//! [`Reported`] in the stage's own file, and the report (`report::Report::tell`) files the
//! [`Facts`] under the stage's entry. The bake itself names no count: adding a stage or an
//! effect adds its facts where its code is.

/// A stage's counts, note and warnings, as its result reports them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Facts {
    /// Named numbers (`welded_vertices`, `fins`, …), filed under the stage's entry.
    pub counts: Vec<(&'static str, f64)>,
    /// What the stage left out, or how it was configured.
    pub note: Option<String>,
    /// Lines for the surface's `warning:` list.
    pub warnings: Vec<String>,
}

impl Facts {
    /// Facts with these counts and no note or warning.
    pub fn counts<const N: usize>(counts: [(&'static str, f64); N]) -> Facts {
        Facts {
            counts: counts.to_vec(),
            ..Default::default()
        }
    }

    /// These facts with `note` (replacing any).
    pub fn with_note(mut self, note: impl Into<String>) -> Facts {
        self.note = Some(note.into());
        self
    }

    /// These facts with `warning` appended.
    pub fn with_warning(mut self, warning: impl Into<String>) -> Facts {
        self.warnings.push(warning.into());
        self
    }
}

/// A stage result that reports on its run.
pub trait Reported {
    fn facts(&self) -> Facts;
}
