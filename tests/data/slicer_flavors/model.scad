union(){ cube([12,12,2]); translate([20,6,0]) cylinder(h=3, r=5, $fn=32); }
