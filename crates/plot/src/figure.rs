/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Style {
    /// Solid line through consecutive finite points.
    #[default]
    Line,
    /// Dashed line through consecutive finite points.
    Dashed,
    /// Hollow circle at every finite point, no line.
    Markers,
    /// Solid line with a hollow circle at every finite point.
    LineMarkers,
    /// Small, faded hollow circles: estimates that are not significant, drawn so that they
    /// read as the noise floor rather than as data.
    FadedMarkers,
    /// A shaded region between `y` (lower edge) and [`Series::upper`] (upper edge), for
    /// confidence regions. A lower edge that is not drawable (NaN, or not positive on a log
    /// axis) while the upper edge is, reaches down to the bottom of the axes.
    Band,
    /// A vertical line from zero (or the nearest edge of the axes) to each value, with a dot:
    /// correlations over lags.
    Stems,
}

impl Style {
    pub(crate) fn has_line(self) -> bool {
        matches!(self, Style::Line | Style::Dashed | Style::LineMarkers)
    }

    pub(crate) fn has_markers(self) -> bool {
        matches!(
            self,
            Style::Markers | Style::LineMarkers | Style::FadedMarkers | Style::Stems
        )
    }
}

/// What a series shows. Every figure draws one meaning in one colour, so the measured data
/// or the nominal model look the same in every file; a series without a role takes the
/// palette colour of its index in the panel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Role {
    /// Measured data: near-black.
    Measured,
    /// The nominal (or configured) model: blue.
    Nominal,
    /// The extended (or refitted) model: orange.
    Extended,
    /// The nominal model with its parameters refitted, beside an extended one: teal.
    Refitted,
    /// The exact theory of the simulated system: green.
    Theory,
    /// A non-parametric estimate and its confidence band: red.
    Estimate,
    /// A second estimate beside the first (another estimator): purple.
    EstimateAlt,
    /// A third estimate: brown.
    EstimateAlt2,
    /// Significance bounds and reference lines: grey.
    Bound,
}

/// Axis scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Values plotted as they are.
    #[default]
    Linear,
    /// Values plotted by their base-10 logarithm; values that are not positive are skipped.
    Log10,
    /// Angles in degrees, plotted as they are, with ticks at multiples of 15, 30, 45, 90 or
    /// 180 degrees when the range spans at least two of them.
    Degrees,
}

/// One labelled curve or point set.
///
/// `x` and `y` must have the same length (checked by [`save`](crate::save)). Points whose
/// coordinates are NaN or infinite, or not positive on a logarithmic axis, are skipped and
/// break a line into separate pieces.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend text; an empty label keeps the series out of the legend.
    pub label: String,
    /// Abscissae in data units.
    pub x: Vec<f64>,
    /// Ordinates in data units.
    pub y: Vec<f64>,
    /// Drawing style.
    pub style: Style,
    /// Colour by meaning; `None` takes the palette colour of the series' index.
    pub role: Option<Role>,
    /// Upper edge of a [`Style::Band`] (same length as `x`); empty for other styles.
    pub upper: Vec<f64>,
}

impl Series {
    /// A series from its label, coordinates and style.
    pub fn new(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>, style: Style) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style,
            role: None,
            upper: Vec::new(),
        }
    }

    /// A shaded band between `lower` and `upper` at `x` ([`Style::Band`]).
    pub fn band(label: impl Into<String>, x: Vec<f64>, lower: Vec<f64>, upper: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y: lower,
            style: Style::Band,
            role: None,
            upper,
        }
    }

    /// The series coloured by its meaning.
    #[must_use]
    pub fn with_role(mut self, role: Role) -> Self {
        self.role = Some(role);
        self
    }
}

/// One set of axes with its series.
///
/// Series are coloured from a fixed palette by their position in `series`, so the n-th series
/// has the same colour in every panel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Panel {
    /// Title drawn above the axes; empty for none.
    pub title: String,
    /// Horizontal axis label, with units.
    pub x_label: String,
    /// Vertical axis label, with units.
    pub y_label: String,
    /// Horizontal axis scale.
    pub x_scale: Scale,
    /// Vertical axis scale.
    pub y_scale: Scale,
    /// Curves in drawing order.
    pub series: Vec<Series>,
    /// Horizontal range in data units; `None` fits the finite data exactly.
    pub x_range: Option<(f64, f64)>,
    /// Vertical range in data units; `None` fits the finite data with a 5 % margin.
    pub y_range: Option<(f64, f64)>,
    /// Named ticks on the horizontal axis, `(position in data units, label)`: when not empty
    /// they replace the automatic ticks (categories, such as the steps of a waterfall).
    pub x_ticks: Vec<(f64, String)>,
}

impl Panel {
    /// An empty panel with linear axes and automatic ranges.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            ..Self::default()
        }
    }
}

/// Panels laid out in a grid, filled row by row, under an optional title.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title drawn above all panels; empty for none.
    pub title: String,
    /// Panels in reading order (left to right, then top to bottom).
    pub panels: Vec<Panel>,
    /// Number of grid columns (at least 1).
    pub columns: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}
