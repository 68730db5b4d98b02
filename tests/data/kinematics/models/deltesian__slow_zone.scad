// centre 0,100
cube([100, 20, 0.6], center=false);
