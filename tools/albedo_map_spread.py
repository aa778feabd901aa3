"""The spread and correlation time of the footprint-weighted reflectivity between the two
families of shipped maps (CERES 2018 annual 1x1 against the TOMS mean 1.25x1), along a
circular orbit: where the filter's `albedo_gain_sigma` and `albedo_gain_time_s` defaults
come from (docs/validation.md, "Another simulator's albedo").

Usage: python3 tools/albedo_map_spread.py [ALTITUDE_KM [SUN_LONGITUDE_DEG]]
(defaults 700 and 30). Standard library only; about half a minute.

A nadir-pointing plate; the Earth in 2x2 deg cells (each the mean of the maps' cells);
each sunlit cell seen by the plate weighs cos(Sun on the cell) cos(view from the cell)
cos(on the plate) dA / (pi d^2). Prints the log ratio's mean and spread over the rows with
albedo and its autocorrelation at lags within one pass.
"""
import math, sys
import os
fx=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'fixtures', 'albedo') + os.sep
toms=[list(map(float,l.split())) for l in open(fx+'earthReflectivityMean_1p25x1.dat') if l.strip()]
ceres=[list(map(float,l.split(','))) for l in open(fx+'Earth_ALB_2018_CERES_All_1x1.csv') if l.strip()]
R=6371.0
# 2x2 deg cells
cells=[]
for ilat in range(0,180,2):
    lat=math.radians(-90+ilat+1)
    for ilon in range(0,360,2):
        lon=math.radians(-180+ilon+1)
        c=sum(ceres[ilat+a][ilon+b] for a in (0,1) for b in (0,1))/4
        # toms: line=lon index (1.25 deg), column = 179-ilat
        tl=int(((math.degrees(lon)+180)/1.25))%288
        t=toms[tl][179-(ilat+1)]/100
        area=R*R*math.radians(2)*math.radians(2)*math.cos(lat)
        p=(R*math.cos(lat)*math.cos(lon),R*math.cos(lat)*math.sin(lon),R*math.sin(lat))
        cells.append((p,c,t,area))
h=float(sys.argv[1]) if len(sys.argv)>1 else 700.0
inc=math.radians(98.0)
rs=R+h
period=2*math.pi*math.sqrt(rs**3/398600.4418)
we=7.2921e-5
sun_lon=math.radians(float(sys.argv[2]) if len(sys.argv)>2 else 30.0)
sun=(math.cos(sun_lon),math.sin(sun_lon),0.0)
dt=30.0
out=[]
t=0.0
while t<3*period:
    u=2*math.pi*t/period
    x=rs*math.cos(u); y=rs*math.sin(u)*math.cos(inc); z=rs*math.sin(u)*math.sin(inc)
    th=-we*t; x,y=x*math.cos(th)-y*math.sin(th), x*math.sin(th)+y*math.cos(th)
    n=(x/rs,y/rs,z/rs)
    ec=et=0.0
    for (p,c,tm,a) in cells:
        cs=(p[0]*sun[0]+p[1]*sun[1]+p[2]*sun[2])/R
        if cs<=0: continue
        d=(x-p[0],y-p[1],z-p[2]); dd=math.sqrt(d[0]**2+d[1]**2+d[2]**2)
        cv=(d[0]*p[0]+d[1]*p[1]+d[2]*p[2])/(R*dd)
        if cv<=0: continue
        cp=(d[0]*n[0]+d[1]*n[1]+d[2]*n[2])/dd
        if cp<=0: continue
        w=cs*cv*cp*a/(math.pi*dd*dd)
        ec+=c*w; et+=tm*w
    if et>1e-3 and ec>1e-3:
        out.append((t,ec,et))
    t+=dt
print('period',period,'points',len(out))
r=[math.log(e[1]/e[2]) for e in out]
m=sum(r)/len(r); s=math.sqrt(sum((x-m)**2 for x in r)/len(r))
print('log ratio ceres/toms mean %.3f std %.3f'%(m,s))
# ratio after removing the mean gain
dev=[x-m for x in r]
# autocorrelation over consecutive points (same pass)
for lag in (1,2,4,8,16,30):
    num=0;cnt=0
    for i in range(len(out)-lag):
        if abs(out[i+lag][0]-out[i][0]-lag*dt)<1e-6:
            num+=dev[i]*dev[i+lag];cnt+=1
    if cnt: print('lag %5.0f s corr %.2f'%(lag*dt,num/cnt/s/s))
