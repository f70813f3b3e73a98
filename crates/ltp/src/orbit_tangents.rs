//! How a system's orbit and its linearisation along it move with some of its parameters: what
//! the derivatives of HTFs taken along the orbit need (`htfid_theory::OrbitHtf::derivatives`).

/// The directions of change of a system's orbit and linearisation, one per parameter `p_j`
/// (`k` of them), exactly: the orbit's own sensitivity `z_j = dx/dp_j` (its dynamics and its
/// jumps at the guards) and the changes of `A`, `B`, `C`, `D` and of the saltation matrices
/// that follow from it. Matrices are row-major; `n` states, `m = 1` input, `p` outputs;
/// sensitivities are `n x k` (column `j` for `p_j`).
///
/// A model that gives its exact derivatives implements it (a model-language model does,
/// `htfid_lang::Model::orbit_tangents`).
pub trait OrbitTangents {
    /// The system's charts.
    type Mode: Copy;

    /// The number of directions `k`.
    fn directions(&self) -> usize;

    /// `z(t0)`, the periodic orbit's sensitivity at the cycle's phase origin (`n x k`).
    fn start(&self) -> &[f64];

    /// `dz = A z + df/dp` at `(mode, t, x)`, for every direction (`z` and `dz` are `n x k`).
    fn sensitivity_field(&self, mode: Self::Mode, t: f64, x: &[f64], z: &[f64], dz: &mut [f64]);

    /// Through the crossing of guard `index` of `mode` at `t` from the pre-crossing state
    /// `x_minus`: `z` from before to after in place, and `dtau[j]`, how fast the crossing's time
    /// moves along direction `j`.
    fn sensitivity_jump(
        &self,
        mode: Self::Mode,
        index: usize,
        t: f64,
        x_minus: &[f64],
        z: &mut [f64],
        dtau: &mut [f64],
    );

    /// The total change of `A` (`n x n`), `B` (`n`), `C` (`p x n`) and `D` (`p`) at
    /// `(mode, t, x)` along every direction `j`, the state moving by column `j` of `z`
    /// (`n x k`): `dA_j = A_{p_j} + sum_l A_{x_l} z_lj`, and so on, direction after direction
    /// (`da` is `k x n x n`, `db` `k x n`, `dc` `k x p x n`, `dd` `k x p`).
    #[allow(clippy::too_many_arguments)] // reason: the point, its motion and four outputs
    fn linearisation_change(
        &self,
        mode: Self::Mode,
        t: f64,
        x: &[f64],
        z: &[f64],
        da: &mut [f64],
        db: &mut [f64],
        dc: &mut [f64],
        dd: &mut [f64],
    );

    /// The total change of the saltation matrix (`n x n`) of guard `index` of `mode`, crossed
    /// at `(t, x_minus)`, along direction `j`, the crossing moved by `dt` in time and `dx`
    /// (`z- + f- dt`) in state: `dS = S_p + S_x dx + S_t dt`.
    #[allow(clippy::too_many_arguments)] // reason: the crossing, the direction and its motion
    fn saltation_change(
        &self,
        mode: Self::Mode,
        index: usize,
        t: f64,
        x_minus: &[f64],
        j: usize,
        dx: &[f64],
        dt: f64,
        ds: &mut [f64],
    );

    /// The total change of the state's jump per unit input (`n`) at the crossing of guard
    /// `index` of `mode` whose guard or reset reads the input
    /// (`InputOutput::crossing_input`: `dR/du + jump dh/du / speed`), along direction `j`, the
    /// crossing moved as in [`OrbitTangents::saltation_change`]; `false` (the default) when the
    /// system does not give it (the derivatives then refuse such a crossing).
    #[allow(clippy::too_many_arguments)] // reason: the crossing, the direction and its motion
    fn input_jump_change(
        &self,
        _mode: Self::Mode,
        _index: usize,
        _t: f64,
        _x_minus: &[f64],
        _j: usize,
        _dx: &[f64],
        _dt: f64,
        _de: &mut [f64],
    ) -> bool {
        false
    }
}
