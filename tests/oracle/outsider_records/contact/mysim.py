import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
P = dict(m=1.0, k=100.0, c=2.0, kc=1000.0, d=0.02, F=3.0, T=0.8)

def rhs_factory(P, ufun, drag=0.0):
    m,k,c,kc,d,F,T = (P[n] for n in "m k c kc d F T".split())
    def f(t, y):
        x, v = y[0], y[1]
        contact = kc*(x+d) if x < -d else 0.0
        a = (-k*x - c*v + F*np.cos(2*np.pi*t/T) + ufun(t) - contact - drag*abs(v)*v)/m
        return [v, a]
    return f

def sim(P, ufun, t_eval, y0, drag=0.0, t0=0.0):
    f = rhs_factory(P, ufun, drag)
    ev = lambda t,y: y[0]+P['d']
    # integrate with events for accuracy: split at contact crossings
    ts=[]; ys=[]
    t=t0; y=np.array(y0,float); tend=t_eval[-1]
    out = np.empty((len(t_eval),2))
    idx=0
    ev.terminal=True
    while t < tend:
        sol = solve_ivp(f,(t,tend),y,method='DOP853',rtol=1e-11,atol=1e-13,events=ev,dense_output=True, max_step=0.01)
        te = sol.t[-1]
        mask = (t_eval>=t)&(t_eval<=te)
        if mask.any(): out[mask] = sol.sol(t_eval[mask]).T
        y = sol.y[:,-1].copy()
        if sol.status==1:
            # step past the event a hair
            t = te
            # nudge: re-integrate a tiny step so the event is not re-detected at start
            s2 = solve_ivp(f,(t,t+1e-9),y,method='DOP853',rtol=1e-12,atol=1e-14)
            y = s2.y[:,-1]; t=t+1e-9
        else:
            t = te
    return out

if __name__ == "__main__":
    T=P['T']
    zero=lambda t:0.0
    y=[0.05,0.0]
    # settle 200 periods
    for i in range(200):
        y = sim(P, zero, np.array([i*T,(i+1)*T]), y, t0=i*T)[-1]
    print("state at phase 0:", y)
    # floquet via finite difference of period map
    def pmap(y0):
        return sim(P, zero, np.array([0,T]), y0)[-1]
    J=np.zeros((2,2)); h=1e-6
    for j in range(2):
        e=np.zeros(2); e[j]=h
        J[:,j]=(pmap(y+e)-pmap(y-e))/(2*h)
    print("J", J, "eig", np.linalg.eigvals(J))
