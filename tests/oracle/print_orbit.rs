//! Prints the closed-form hopper orbit for the paper parameters as JSON, so
//! `hopper_htf.py --check-rust` can compare it with the Python oracle.
//!
//! Build: `rustc --edition 2021 -O tests/oracle/print_orbit.rs -o /tmp/print_orbit`.

#[path = "hopper_closed_form.rs"]
mod hopper_closed_form;

fn main() {
    let o = hopper_closed_form::hopper_orbit(1.0, 200.0, 2.0, 9.81, 0.2, 1.0, 1.0);
    let m = o.monodromy;
    println!(
        "{{\"t_on\": {:e}, \"t_off\": {:e}, \"duty\": {:e}, \"x_on\": {:e}, \"x_off\": {:e}, \
         \"x_phase0\": {:e}, \"v_phase0\": {:e}, \
         \"floquet\": [[{:e}, {:e}], [{:e}, {:e}]], \
         \"monodromy\": [[{:e}, {:e}], [{:e}, {:e}]]}}",
        o.t_on,
        o.t_off,
        o.duty(),
        o.x_on,
        o.x_off,
        o.x_phase0,
        o.v_phase0,
        o.floquet[0].0,
        o.floquet[0].1,
        o.floquet[1].0,
        o.floquet[1].1,
        m[0][0],
        m[0][1],
        m[1][0],
        m[1][1]
    );
}
