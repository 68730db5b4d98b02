difference() { cylinder(r=99.47, h=1.2, $fn=360); translate([0, 0, -1]) cylinder(r=87.47, h=5, $fn=360); }
