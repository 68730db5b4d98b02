difference() { cylinder(r=56.89, h=1.2, $fn=360); translate([0, 0, -1]) cylinder(r=47.39, h=5, $fn=360); }
