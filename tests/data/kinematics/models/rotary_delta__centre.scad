// centre 0,0
cylinder(d=30, h=3, $fn=96);
