import sys, json, subprocess, numpy as np
sys.path.insert(0, '/tmp/judge11')
from gen import Truth
from scipy.interpolate import CubicSpline
base = open('/tmp/judge11/simchk/nominal.toml').read()
cases = [('nominal', {}, ''),
         ('k3', {'k3': 2000.0}, 'k3 = 2000.0'),
         ('mu', {'mu': 0.03}, 'mu = 0.03'),
         ('c_f', {'c_f': 0.3}, 'c_f = 0.3'),
         ('c2', {'c2': 5.0}, 'c2 = 5.0'),
         ('tau', {'tau': 0.02}, 'tau = 0.02'),
         ('delay', {'delay': 0.02}, 'delay = 0.02'),
         ('v_th', {'v_th': 0.01}, 'v_th = 0.01'),
         ('stop', {'x_stop': 0.1445, 'k_stop': 2000.0}, 'x_stop = 0.1445\nk_stop = 2000.0'),
         ('offset', {'input_offset': 0.1}, 'input_offset = 0.1')]
res = {}
for name, eff, toml in cases:
    cfg = base + ('\n[effects]\n' + toml + '\n' if toml else '')
    open(f'/tmp/judge11/simchk/{name}.toml', 'w').write(cfg)
    subprocess.run(['/work/main/target/release/htfid', 'simulate', f'/tmp/judge11/simchk/{name}.toml', '--out', f'/tmp/judge11/simchk/out_{name}', '--force', '-q'], check=True)
    d = np.genfromtxt(f'/tmp/judge11/simchk/out_{name}/timeseries.csv', delimiter=',', names=True)
    t, f, x = d['t'], d['f'], d['x']
    tr = Truth(eff, splinef=CubicSpline(t, f))
    st = tr.simulate(-30.0, t)
    err = st[:, 0] - x
    res[name] = dict(max_abs=float(np.max(np.abs(err))), rms=float(np.sqrt(np.mean(err**2))), x_std=float(np.std(x)))
    print(name, res[name], flush=True)
json.dump(res, open('/tmp/judge11/simcheck.json', 'w'), indent=1)
