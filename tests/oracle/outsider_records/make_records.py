import sys, json, os, time, numpy as np
sys.path.insert(0, '/tmp/judge11')
from gen import Truth, Multisine, measure, NOM
from multiprocessing import Pool

DUR = 150.0
R = '/tmp/judge11/records'
k2m = 0.03 * (2 * np.pi * 6.0) ** 2
RECS = [
 # name, group, effects, truth-labels, fs, noise
 ('c1-clean', 'clean', {}, ['none'], 100, 2e-5),
 ('c2-clean-lownoise', 'clean', {}, ['none'], 100, 2e-6),
 ('c3-clean-500Hz', 'clean', {}, ['none'], 500, 2e-5),
 ('c4-clean-500Hz-highnoise', 'clean', {}, ['none'], 500, 1e-4),
 ('s01-cubic', 'single', {'k3': 3000.0}, ['cubic_stiffness'], 100, 2e-5),
 ('s02-cubic-small', 'single', {'k3': 800.0}, ['cubic_stiffness'], 100, 2e-5),
 ('s03-cubic-negative', 'single', {'k3': -3000.0}, ['cubic_stiffness'], 100, 2e-5),
 ('s04-coulomb', 'single', {'mu': 0.03}, ['coulomb_friction'], 100, 2e-5),
 ('s05-asym-friction', 'single', {'mu_pos': 0.04, 'mu_neg': 0.01}, ['asymmetric_friction'], 100, 2e-5),
 ('s06-flight-damping', 'single', {'c_f': 0.2}, ['flight_damping'], 100, 2e-5),
 ('s07-quad-drag', 'single', {'c2': 10.0}, ['quadratic_drag'], 100, 2e-5),
 ('s08-actuator-lag', 'single', {'tau': 0.02}, ['actuator_lag'], 100, 2e-5),
 ('s09-input-delay', 'single', {'delay': 0.015}, ['input_delay'], 100, 2e-5),
 ('s10-input-delay-small', 'single', {'delay': 0.005}, ['input_delay'], 100, 2e-5),
 ('s11-input-offset', 'single', {'input_offset': 0.1}, ['input_offset'], 100, 2e-5),
 ('s12-input-offset-neg', 'single', {'input_offset': -0.1}, ['input_offset'], 100, 2e-5),
 ('s13-switch-threshold', 'single', {'v_th': 0.01}, ['switch_threshold'], 100, 2e-5),
 ('s14-switch-threshold-neg', 'single', {'v_th': -0.01}, ['switch_threshold'], 100, 2e-5),
 ('s15-hard-stop', 'single', {'x_stop': 0.1445, 'k_stop': 2000.0}, ['hard_stop'], 100, 2e-5),
 ('s16-param-error', 'single', {'nom': {'k': 210.0, 'c': 2.2}}, ['parameter_error'], 100, 2e-5),
 ('s17-sensor-lag', 'single', {'tau_s': 0.01}, ['sensor_lag'], 100, 2e-5),
 ('s18-sensor-offset-gain', 'single', {'sensor_offset': 0.002, 'sensor_gain': 1.05}, ['sensor_offset_gain'], 100, 2e-5),
 ('s20-coulomb-large', 'single', {'mu': 0.1}, ['coulomb_friction'], 100, 2e-5),
 ('s21-mass-error', 'single', {'nom': {'m': 1.05}}, ['parameter_error'], 100, 2e-5),
 ('s19-cubic-500Hz', 'single', {'k3': 3000.0}, ['cubic_stiffness'], 500, 2e-5),
 ('p1-coulomb+cubic', 'pair', {'mu': 0.03, 'k3': 3000.0}, ['coulomb_friction', 'cubic_stiffness'], 100, 2e-5),
 ('p2-lag+stop', 'pair', {'tau': 0.02, 'x_stop': 0.1445, 'k_stop': 2000.0}, ['actuator_lag', 'hard_stop'], 100, 2e-5),
 ('p3-sensorOG+drag', 'pair', {'sensor_offset': 0.002, 'sensor_gain': 1.05, 'c2': 10.0}, ['sensor_offset_gain', 'quadratic_drag'], 100, 2e-5),
 ('p4-flightdamp+delay', 'pair', {'c_f': 0.2, 'delay': 0.015}, ['flight_damping', 'input_delay'], 100, 2e-5),
 ('p5-threshold+offset', 'pair', {'v_th': 0.01, 'input_offset': 0.1}, ['switch_threshold', 'input_offset'], 100, 2e-5),
 ('o1-backlash', 'outside', {'backlash': 0.02}, ['outside'], 100, 2e-5),
 ('o2-second-mode', 'outside', {'m2': 0.03, 'k2': k2m, 'c2m': 2 * 0.05 * np.sqrt(k2m * 0.03)}, ['outside'], 100, 2e-5),
 ('o3-xv-force', 'outside', {'a_xv': 100.0}, ['outside'], 100, 2e-5),
 ('o4-amp-drift', 'outside', {'amp_mod': (0.05, 40.0)}, ['outside'], 100, 2e-5),
]

CFG = '''name = "{name}"
[data]
file = "record.csv"
time = "t"
input = "f"
output = "x"
[model]
m = 1.0
k = 200.0
c = 2.0
g = 9.81
x0 = 0.2
damper = "switching"
free = ["k", "c"]
[forcing]
amplitude = 1.0
period = 1.0
[diagnose]
significance_sigma = 5.0
min_gain = 0.05
'''

def make(rec):
    name, group, eff, labels, fs, noise = rec
    eff = dict(eff)
    nom = eff.pop('nom', None)
    d = os.path.join(R, name); os.makedirs(d, exist_ok=True)
    exc = Multisine(rms=0.1, seed=11)
    tr = Truth(eff, nom=nom, exc=exc)
    t = np.arange(int(round(DUR * fs)) + 1) / fs
    t0 = time.time()
    st = tr.simulate(-60.0, t)
    import zlib; seed = zlib.crc32(name.encode()) % 10000
    x = measure(tr, st, noise, seed)
    f = np.array([tr.f_rec(ti) for ti in t])
    assert np.all(np.isfinite(x))
    with open(os.path.join(d, 'record.csv'), 'w') as fh:
        fh.write('t,f,x\n')
        for a, b, c in zip(t, f, x):
            fh.write(f'{a:.10g},{b:.17g},{c:.17g}\n')
    truth = dict(name=name, group=group, labels=labels, effects={k: (list(v) if isinstance(v, tuple) else v) for k, v in eff.items()},
                 nominal_truth=dict(NOM, **(nom or {})), fs=fs, noise=noise, duration=DUR,
                 excitation=dict(kind='multisine', rms=0.1, fmin=0.2, fmax=10.0, df=0.1, seed=11),
                 x_true_min=float(st[:, 0].min()), x_true_max=float(st[:, 0].max()), v_absmax=float(np.abs(st[:, 1]).max()),
                 switches=tr.nsw, gen_s=time.time() - t0, noise_seed=seed)
    json.dump(truth, open(os.path.join(d, 'truth.json'), 'w'), indent=1)
    open(os.path.join(d, 'diagnose.toml'), 'w').write(CFG.format(name=name))
    return name, truth['gen_s'], truth['x_true_min'], truth['x_true_max'], truth['v_absmax']

if __name__ == '__main__':
    sel = sys.argv[1:]
    recs = [r for r in RECS if not sel or r[0] in sel]
    with Pool(2) as p:
        for r in p.imap_unordered(make, recs):
            print(r, flush=True)
