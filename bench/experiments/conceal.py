#!/usr/bin/env python3
"""Concealment of lost region packets, three ways (issue 23's design experiment).

    python3 bench/experiments/conceal.py IMAGE RATE LOSS

Encodes IMAGE (gray) into 255-byte packets at RATE bpp, loses LOSS of them with seeds 1-5
(`pifs packets drop`), and compares the PSNR of the lost regions filled with the preview (what
`pifs decode` does), with the preview plus the difference between the received pixels and the
preview interpolated across each lost region from its border, and with the received pixels
interpolated alone (row and column, averaged). Runs with the preview received only. PIFS and
WORK (environment) name the `pifs` binary and a scratch directory.
"""
import os, sys, subprocess, shutil, numpy as np
from PIL import Image
PIFS=os.environ.get("PIFS", "target/release/pifs")
def varint(b,pos):
    v=0;k=0
    while True:
        c=b[pos];pos+=1;v|=(c&0x7f)<<(7*k);k+=1
        if c&0x80==0: return v,pos
def parse(b):
    flags=b[4];pos=5
    idx,pos=varint(b,pos);cnt,pos=varint(b,pos);w,pos=varint(b,pos);h,pos=varint(b,pos)
    if flags&2: return idx,None,w,h
    r=[]
    for _ in range(4):
        v,pos=varint(b,pos);r.append(v*8)
    return idx,r,w,h
def lininterp(vals,mask):
    # mean of row and column linear interpolation between nearest covered pixels
    H,W=vals.shape
    out=np.zeros_like(vals);wt=np.zeros_like(vals)
    for axis in (0,1):
        V=vals if axis==1 else vals.T; M=mask if axis==1 else mask.T
        O=np.zeros_like(V);Wt=np.zeros_like(V)
        for i in range(V.shape[0]):
            idx=np.nonzero(M[i])[0]
            if len(idx)==0: continue
            x=np.arange(V.shape[1])
            O[i]=np.interp(x,idx,V[i,idx]);Wt[i]=1
        if axis==0: O=O.T;Wt=Wt.T
        out+=O;wt+=Wt
    return out/np.maximum(wt,1)
def psnr(a,b): return 10*np.log10(255**2/np.mean((a-b)**2))
img=sys.argv[1]; rate=sys.argv[2]; loss=sys.argv[3]
work=os.environ.get("WORK", "target/conceal"); shutil.rmtree(work,ignore_errors=True); os.makedirs(work)
orig=np.asarray(Image.open(img).convert('L'),dtype=float)
pk=work+"/pk"
subprocess.run([PIFS,"encode",img,"--gray","--bpp",rate,"--packets",pk],check=True,capture_output=True)
subprocess.run([PIFS,"decode",pk+"/0000.pkt","-o",work+"/prev.png"],check=True,capture_output=True)
prev=np.asarray(Image.open(work+"/prev.png"),dtype=float)
res={"preview":[], "corrected":[], "interp":[]}
for seed in range(1,6):
    shutil.rmtree(work+"/l",ignore_errors=True)
    subprocess.run([PIFS,"packets","drop","--loss",loss,"--seed",str(seed),pk,work+"/l"],check=True,capture_output=True)
    if not os.path.exists(work+"/l/0000.pkt"): continue
    subprocess.run([PIFS,"decode",work+"/l","-o",work+"/d.png"],check=True,capture_output=True)
    d=np.asarray(Image.open(work+"/d.png"),dtype=float)
    mask=np.zeros(orig.shape,bool)
    for f in os.listdir(work+"/l"):
        i,r,w,h=parse(open(work+"/l/"+f,'rb').read())
        if r: mask[r[1]:r[1]+r[3], r[0]:r[0]+r[2]]=True
    resid=np.where(mask,d-prev,0)
    corr=np.where(mask,d,np.clip(np.round(prev+lininterp(resid,mask)),0,255))
    interp=np.where(mask,d,np.round(lininterp(d,mask)))
    res["preview"].append(psnr(d,orig));res["corrected"].append(psnr(corr,orig));res["interp"].append(psnr(interp,orig))
print(img.split('/')[-1],rate,loss,{k:round(float(np.mean(v)),2) for k,v in res.items()})
