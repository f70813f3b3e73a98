import numpy as np, sys
from mysim import sim, P
rng=np.random.default_rng(11)
fs=250.0; Tend=60.0
t=np.arange(0,Tend+1e-9,1/fs)
# multisine input, 0.3-6 Hz, random phases
fr=np.arange(0.05,6.0,0.05)
ph=rng.uniform(0,2*np.pi,len(fr))
amp=0.4/np.sqrt(len(fr)/2)
def ufun(tt, delay=0.0):
    tt=np.asarray(tt)-delay
    return amp*np.sum(np.cos(2*np.pi*np.multiply.outer(tt,fr)+ph),axis=-1)
y0=[0.02281011497003592,0.08830651297389902]
def make(name, drag=0.0, delay=0.0, gain=1.0, noise=2e-5, Pover=None):
    PP=dict(P); PP.update(Pover or {})
    xs=sim(PP, lambda tt: float(ufun(tt,delay)), t, y0, drag=drag)[:,0]
    x=gain*xs+noise*rng.standard_normal(len(t))
    u=ufun(t)
    np.savetxt(name, np.column_stack([t,u,x]), delimiter=",", header="t,u,x", comments="", fmt="%.10g")
    print(name, "x std", x.std(), "u std", u.std())
which=sys.argv[1:]
if "clean" in which: make("rec_clean.csv")
if "drag" in which: make("rec_drag.csv", drag=1.0)
if "delay" in which: make("rec_delay.csv", delay=0.02)
if "gain" in which: make("rec_gain.csv", gain=1.05)
if "k" in which: make("rec_k.csv", Pover={'k':110.0})
if "total" in which:
    # drag record, but column f = total applied force (forcing + u); model has F = 0
    xs=sim(P, lambda tt: float(ufun(tt)), t, y0, drag=1.0)[:,0]
    x=xs+2e-5*rng.standard_normal(len(t))
    f=ufun(t)+P['F']*np.cos(2*np.pi*t/P['T'])
    np.savetxt("rec_total.csv", np.column_stack([t,f,x]), delimiter=",", header="t,f,x", comments="", fmt="%.10g")
if "kc" in which: make("rec_kc.csv", Pover={'kc':1500.0})
if "lag" in which:
    tau=0.03
    H=1/(1+1j*2*np.pi*fr*tau)
    def ulag(tt):
        return amp*np.sum(np.abs(H)*np.cos(2*np.pi*np.multiply.outer(np.asarray(tt),fr)+ph+np.angle(H)),axis=-1)
    # start from steady state of the lag filter (periodic multisine, period 20 s): analytic form is exact steady state
    xs=sim(P, lambda tt: float(ulag(tt)), t, y0)[:,0]
    x=xs+2e-5*rng.standard_normal(len(t)); u=ufun(t)
    np.savetxt("rec_lag.csv", np.column_stack([t,u,x]), delimiter=",", header="t,u,x", comments="", fmt="%.10g")
if "unoise" in which:
    xs=sim(P, lambda tt: float(ufun(tt)), t, y0)[:,0]
    x=xs+2e-5*rng.standard_normal(len(t)); u=ufun(t)+0.004*rng.standard_normal(len(t))
    np.savetxt("rec_unoise.csv", np.column_stack([t,u,x]), delimiter=",", header="t,u,x", comments="", fmt="%.10g")
